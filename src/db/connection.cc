// Opening, configuring and migrating the database; transactions.

#include <fmt/format.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <iterator>

#include "database_internal.h"
#include "epiloc/core/error.h"
#include "epiloc/db/database.h"

namespace epiloc {
namespace {

struct Migration {
  int version;       // 1, 2, ... from the file name NNNN_*.sql
  const char* name;  // file name, for messages
  const char* sql;
};

#include "schema_migrations.inc"

constexpr int kLatestSchemaVersion =
    kMigrations[std::size(kMigrations) - 1].version;
// Long enough to ride out another writer's short transaction, short enough
// that a database held by a long-running writer fails promptly.
constexpr int kBusyTimeoutMs = 2000;

// True if a file can be created in the folder of `path` (access(2) also reports read-only mounts).
bool FolderWritable(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return ::access(parent.empty() ? "." : parent.c_str(), W_OK) == 0;
}

// `path` for a file: URI (RFC 3986 reserved characters that SQLite's URI parser would read).
std::string UriEscape(const std::string& path) {
  std::string out;
  for (const char c : path) {
    if (c == '%' || c == '?' || c == '#') {
      out += fmt::format("%{:02x}", static_cast<unsigned char>(c));
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

namespace internal {

int CheckSqlite(int rc,
                sqlite3* db,
                const std::string& path,
                std::string_view what) {
  if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return rc;
  switch (rc & 0xff) {
    case SQLITE_BUSY:
      Throw("{}: database is locked by another process", path);
    case SQLITE_NOTADB:
      Throw("{}: not an SQLite database ({}: file is not a database)", path,
            what);
    default:
      break;
  }
  const char* message = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  Throw("{}: {}: {}", path, what, message);
}

}  // namespace internal

using internal::Query;

Database::Impl::Impl(const std::string& path, Mode mode) : path_(path) {
  int flags = mode == Mode::kReadOnly ? SQLITE_OPEN_READONLY
                                      : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE;
  std::string open_path = path;
  const bool on_disk = path != ":memory:" && !path.empty();
  if (on_disk && mode == Mode::kReadOnly && !FolderWritable(path)) {
    // Even a reader of a WAL database creates <db>-shm beside it, which read-only media refuse
    // ("attempt to write a readonly database"). Where no -shm can be made no SQLite writer can
    // work either, so the file cannot change under us: open it immutable.
    std::error_code error;
    if (std::filesystem::file_size(path + "-wal", error) > 0 && !error) {
      Throw(
          "{}: its write-ahead log {}-wal holds changes not yet merged and the folder is "
          "read-only: run any epiloc command on it once where it can be written",
          path, path);
    }
    open_path = "file:" + UriEscape(path) + "?immutable=1";
    flags |= SQLITE_OPEN_URI;
  }
  if (on_disk && mode == Mode::kReadWrite && std::filesystem::exists(path) &&
      (!FolderWritable(path) || ::access(path.c_str(), W_OK) != 0)) {
    Throw("{}: the database (or its folder) is read-only, and this command writes to it", path);
  }
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(open_path.c_str(), &db, flags, nullptr);
  connection_.reset(db);  // closed on every path, also when opening failed
  Check(rc, "opening the database");
  Check(sqlite3_extended_result_codes(db, 1), "enabling extended codes");
  Check(sqlite3_busy_timeout(db, kBusyTimeoutMs), "setting the busy timeout");
  Exec("PRAGMA foreign_keys = ON", "enabling foreign keys");

  // The first read of the file: a file that is not SQLite fails here.
  const int version = static_cast<int>(
      QueryInt("PRAGMA user_version", "reading the schema version"));
  CheckNotNewer(version);
  if (mode == Mode::kReadOnly) {
    if (version == 0) {
      Throw("{}: not an epiloc database (schema version 0)", path_);
    }
    if (version < kLatestSchemaVersion) {
      Throw(
          "{}: database schema version {} is older than this epiloc ({}); "
          "open it for writing once to migrate it",
          path_, version, kLatestSchemaVersion);
    }
  } else {
    // Before switching to WAL, which would persist in another program's database and leave
    // -wal/-shm files beside it.
    if (version == 0) RefuseForeignTables();
    if (on_disk) {
      Exec("PRAGMA journal_mode = WAL", "enabling write-ahead logging");
      wal_writer_ = true;
    }
    Exec("PRAGMA synchronous = NORMAL", "setting synchronous mode");
    if (version < kLatestSchemaVersion) Migrate();
  }
  PrepareStatements();
}

// WAL while a writer works (a reader is never blocked by it, nor it by a reader), but a
// rollback journal at rest. SQLite removes <db>-wal and <db>-shm when the last connection closes
// only if that connection can write: a read-only one (every reading command) leaves both behind,
// empty, for a WAL-mode file. In rollback-journal mode a reader needs no file beside the
// database, so reading commands leave the folder as they found it. Leaving WAL mode needs the
// database to itself: with another connection open (a concurrent reader or build) it fails at
// once and the file stays in WAL mode; the last writer to close switches it.
Database::Impl::~Impl() {
  if (!wal_writer_ || db() == nullptr) return;
  statements_.clear();
  sqlite3_busy_timeout(db(), 0);
  // A destructor must not throw; a failure leaves a valid WAL-mode database.
  sqlite3_exec(db(), "PRAGMA journal_mode = DELETE", nullptr, nullptr, nullptr);
}

void Database::Impl::Exec(const std::string& sql, std::string_view what) {
  Check(sqlite3_exec(db(), sql.c_str(), nullptr, nullptr, nullptr), what);
}

sqlite3_stmt* Database::Impl::Prepare(const std::string& sql) {
  sqlite3_stmt* stmt = nullptr;
  const int rc =
      sqlite3_prepare_v3(db(), sql.c_str(), static_cast<int>(sql.size()) + 1,
                         SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
  if (stmt != nullptr) statements_.emplace_back(stmt);
  Check(rc, fmt::format("preparing '{}'", sql));
  return stmt;
}

int64_t Database::Impl::QueryInt(const char* sql, std::string_view what) {
  sqlite3_stmt* stmt = nullptr;
  Check(sqlite3_prepare_v2(db(), sql, -1, &stmt, nullptr), what);
  const std::unique_ptr<sqlite3_stmt, internal::StatementFinalizer> owner(stmt);
  Query query(stmt, path_, what);
  return query.Step() ? query.Int() : 0;
}

void Database::Impl::RefuseForeignTables() {
  // Tables in a version-0 file belong to another program: never add ours.
  const int64_t tables =
      QueryInt("SELECT count(*) FROM sqlite_schema WHERE name NOT LIKE 'sqlite_%'",
               "reading the schema");
  if (tables > 0) {
    Throw("{}: an SQLite database but not an epiloc one (schema version 0 and {} tables)", path_,
          tables);
  }
}

void Database::Impl::CheckNotNewer(int version) const {
  if (version > kLatestSchemaVersion) {
    Throw(
        "{}: database schema version {} is newer than this epiloc ({}); "
        "upgrade epiloc",
        path_, version, kLatestSchemaVersion);
  }
}

// All missing migrations and the new user_version in one transaction, so a
// failure leaves the file as it was.
void Database::Impl::Migrate() {
  Exec("BEGIN IMMEDIATE", "starting the schema migration");
  try {
    // Again under the write lock: another process may have migrated meanwhile.
    const int version = static_cast<int>(
        QueryInt("PRAGMA user_version", "reading the schema version"));
    CheckNotNewer(version);
    if (version == 0) RefuseForeignTables();
    for (const Migration& migration : kMigrations) {
      if (migration.version <= version) continue;
      Exec(migration.sql, fmt::format("applying migration {}", migration.name));
    }
    Exec(fmt::format("PRAGMA user_version = {}", kLatestSchemaVersion),
         "setting the schema version");
    Exec("COMMIT", "committing the schema migration");
  } catch (...) {
    // Already failing: a failed rollback must not replace the first error.
    if (sqlite3_get_autocommit(db()) == 0) {
      sqlite3_exec(db(), "ROLLBACK", nullptr, nullptr, nullptr);
    }
    throw;
  }
}

int Database::LatestSchemaVersion() { return kLatestSchemaVersion; }

Database::Database(const std::string& path, Mode mode)
    : path_(path), impl_(std::make_unique<Impl>(path, mode)) {}

Database::~Database() = default;

int Database::SchemaVersion() const {
  Query query(impl_->schema_version, path_, "reading the schema version");
  return query.Step() ? static_cast<int>(query.Int()) : 0;
}

Database::Transaction::Transaction(Database& database) : database_(database) {
  Impl& impl = *database_.impl_;
  EPILOC_CHECK(sqlite3_get_autocommit(impl.db()) != 0,
               "{}: a transaction is already active (transactions do not nest)",
               database_.path_);
  Query(impl.begin, database_.path_, "starting a transaction").Run();
}

Database::Transaction::~Transaction() {
  if (done_) return;
  Impl& impl = *database_.impl_;
  // SQLite may already have rolled back after an I/O error; never throw here.
  if (sqlite3_get_autocommit(impl.db()) != 0) return;
  try {
    Query(impl.rollback, database_.path_, "rolling back a transaction").Run();
  } catch (const Error&) {
  }
}

void Database::Transaction::Commit() {
  EPILOC_CHECK(!done_, "{}: transaction committed twice", database_.path_);
  Query(database_.impl_->commit, database_.path_, "committing a transaction")
      .Run();
  done_ = true;
}

}  // namespace epiloc
