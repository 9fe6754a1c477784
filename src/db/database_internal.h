// Internals of the db module shared by its sources: the one SQLite error
// checker, the statement guard and the connection with its prepared statements.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "epiloc/db/database.h"

namespace epiloc {
namespace internal {

// The one place where an SQLite result code becomes an exception: returns `rc`
// if it is SQLITE_OK, SQLITE_ROW or SQLITE_DONE, else throws Error
// "<path>: <what>: <sqlite message>" (SQLITE_BUSY: "<path>: database is locked
// by another process"). Every sqlite3_* call that reports an error goes through
// it; only clean-up in destructors ignores codes, as it must not throw.
int CheckSqlite(int rc,
                sqlite3* db,
                const std::string& path,
                std::string_view what);

struct ConnectionCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
struct StatementFinalizer {
  void operator()(sqlite3_stmt* stmt) const { sqlite3_finalize(stmt); }
};

// Binds, steps and reads one prepared statement, with parameters and columns
// taken in order. Resets the statement and clears its bindings when it goes out
// of scope, also during an exception, so the cached statement is always ready
// for its next use. `path` must outlive the query.
class Query {
 public:
  Query(sqlite3_stmt* stmt, const std::string& path, std::string_view what)
      : stmt_(stmt), db_(sqlite3_db_handle(stmt)), path_(path), what_(what) {}
  ~Query() {
    // The codes repeat the last step's error, which was already reported.
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  Query(const Query&) = delete;
  Query& operator=(const Query&) = delete;

  Query& Bind(int64_t value) {
    return Checked(sqlite3_bind_int64(stmt_, next_bind_++, value));
  }
  Query& Bind(int value) { return Bind(static_cast<int64_t>(value)); }
  Query& Bind(double value) {
    return Checked(sqlite3_bind_double(stmt_, next_bind_++, value));
  }
  Query& Bind(const std::string& value) {
    return Checked(sqlite3_bind_text64(stmt_, next_bind_++, value.data(),
                                       value.size(), SQLITE_TRANSIENT,
                                       SQLITE_UTF8));
  }
  Query& BindNull() { return Checked(sqlite3_bind_null(stmt_, next_bind_++)); }
  // An empty buffer binds a zero-length blob (a null pointer would bind NULL).
  Query& BindBlob(const std::vector<uint8_t>& bytes) {
    static const uint8_t kEmpty = 0;
    const void* data = bytes.empty() ? &kEmpty : bytes.data();
    return Checked(sqlite3_bind_blob64(stmt_, next_bind_++, data, bytes.size(),
                                       SQLITE_TRANSIENT));
  }

  // True when a row is available, false when done.
  bool Step() {
    next_column_ = 0;
    return CheckSqlite(sqlite3_step(stmt_), db_, path_, what_) == SQLITE_ROW;
  }
  // Runs a statement that returns no rows.
  void Run() { Step(); }

  bool IsNull() const {
    return sqlite3_column_type(stmt_, next_column_) == SQLITE_NULL;
  }
  void Skip() { ++next_column_; }
  int64_t Int() { return sqlite3_column_int64(stmt_, next_column_++); }
  double Double() { return sqlite3_column_double(stmt_, next_column_++); }
  std::string Text() {
    const auto* text = sqlite3_column_text(stmt_, next_column_);
    const int size = sqlite3_column_bytes(stmt_, next_column_++);
    if (text == nullptr) return std::string();
    return std::string(reinterpret_cast<const char*>(text), size);
  }
  // Pointer and size of a blob column (nullptr for a zero-length blob), valid
  // until the next step or reset.
  std::pair<const uint8_t*, int64_t> Blob() {
    const auto* data =
        static_cast<const uint8_t*>(sqlite3_column_blob(stmt_, next_column_));
    const int64_t size = sqlite3_column_bytes(stmt_, next_column_++);
    return {data, size};
  }

 private:
  Query& Checked(int rc) {
    CheckSqlite(rc, db_, path_, what_);
    return *this;
  }

  sqlite3_stmt* stmt_;
  sqlite3* db_;
  const std::string& path_;
  std::string_view what_;
  int next_bind_ = 1;
  int next_column_ = 0;
};

}  // namespace internal

// The connection: opened, configured and migrated by the constructor
// (connection.cc); its statements are prepared once (database.cc, next to the
// code that reads their columns) and finalized with it.
class Database::Impl {
 public:
  Impl(const std::string& path, Mode mode);
  // A writer of a file leaves it in rollback-journal mode (see connection.cc).
  ~Impl();
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  sqlite3* db() const { return connection_.get(); }
  const std::string& path() const { return path_; }

  int Check(int rc, std::string_view what) const {
    return internal::CheckSqlite(rc, db(), path_, what);
  }
  // Runs one or more statements that return no rows.
  void Exec(const std::string& sql, std::string_view what);

  sqlite3_stmt* schema_version = nullptr;
  sqlite3_stmt* begin = nullptr;
  sqlite3_stmt* commit = nullptr;
  sqlite3_stmt* rollback = nullptr;
  sqlite3_stmt* savepoint = nullptr;
  sqlite3_stmt* release = nullptr;
  sqlite3_stmt* rollback_to = nullptr;
  sqlite3_stmt* set_meta = nullptr;
  sqlite3_stmt* get_meta = nullptr;
  sqlite3_stmt* write_camera = nullptr;
  sqlite3_stmt* read_camera = nullptr;
  sqlite3_stmt* write_drive = nullptr;
  sqlite3_stmt* update_drive = nullptr;
  sqlite3_stmt* find_drive = nullptr;
  sqlite3_stmt* read_drives = nullptr;
  sqlite3_stmt* write_frame = nullptr;
  sqlite3_stmt* has_frame = nullptr;
  sqlite3_stmt* read_frame = nullptr;
  sqlite3_stmt* read_drive_frames = nullptr;
  sqlite3_stmt* read_all_frames = nullptr;
  sqlite3_stmt* count_drive_frames = nullptr;
  sqlite3_stmt* count_frames = nullptr;
  sqlite3_stmt* count_features = nullptr;
  sqlite3_stmt* write_keypoints = nullptr;
  sqlite3_stmt* read_keypoints = nullptr;
  sqlite3_stmt* write_descriptors = nullptr;
  sqlite3_stmt* read_descriptors = nullptr;
  sqlite3_stmt* clear_route = nullptr;
  sqlite3_stmt* write_route_point = nullptr;
  sqlite3_stmt* read_route = nullptr;
  sqlite3_stmt* delete_frame = nullptr;
  sqlite3_stmt* delete_drive = nullptr;
  sqlite3_stmt* delete_unused_camera = nullptr;
  sqlite3_stmt* delete_meta = nullptr;
  sqlite3_stmt* write_retrieval_model = nullptr;
  sqlite3_stmt* read_retrieval_model = nullptr;
  sqlite3_stmt* delete_retrieval_model = nullptr;
  sqlite3_stmt* write_global_descriptor = nullptr;
  sqlite3_stmt* read_global_descriptors = nullptr;
  sqlite3_stmt* count_global_descriptors = nullptr;
  sqlite3_stmt* clear_global_descriptors = nullptr;
  sqlite3_stmt* write_point = nullptr;
  sqlite3_stmt* write_observation = nullptr;
  sqlite3_stmt* read_frame_points = nullptr;
  sqlite3_stmt* count_points = nullptr;
  sqlite3_stmt* count_observations = nullptr;
  sqlite3_stmt* clear_points = nullptr;

 private:
  // Runs a one-off query returning one integer (0 if no row).
  int64_t QueryInt(const char* sql, std::string_view what);
  void CheckNotNewer(int version) const;
  // Throws Error if a schema-version-0 file holds tables (another program's database).
  void RefuseForeignTables();
  void Migrate();
  void PrepareStatements();
  sqlite3_stmt* Prepare(const std::string& sql);

  std::string path_;
  bool wal_writer_ = false;  // switched an on-disk file to WAL: switches it back when closing
  std::unique_ptr<sqlite3, internal::ConnectionCloser> connection_;
  // Declared after the connection, so finalized before it is closed.
  std::vector<std::unique_ptr<sqlite3_stmt, internal::StatementFinalizer>>
      statements_;
};

}  // namespace epiloc
