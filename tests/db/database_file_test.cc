// The database as a file: migrations from older versions, refusals (newer schema, not SQLite,
// missing directory, locked), read-only mode, the retrieval tables.
#include <sched.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <string>

#include "db_test_util.h"

namespace epiloc {
namespace {

TEST_F(DatabaseFileTest, MigratesAnEmptyVersionZeroFile) {
  const std::string path = PathOf("empty.db");
  {
    RawConnection raw(path);
    raw.Exec("PRAGMA user_version = 0");
  }
  {
    Database db(path);
    EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"),
            Database::LatestSchemaVersion());
  EXPECT_EQ(
      raw.QueryInt("SELECT count(*) FROM sqlite_schema WHERE name = 'frames'"),
      1);
  // WAL only while a writer has it open: at rest a rollback journal, so readers need no files
  // beside it (issue 18, leftovers).
  EXPECT_EQ(raw.QueryText("PRAGMA journal_mode"), "delete");
}

TEST_F(DatabaseFileTest, MigratesEveryOlderVersionAndKeepsItsData) {
  // A database made by hand with the first k migration files (as an older
  // epiloc left it), for every k below the latest; opening it applies the rest.
  // k = latest is a database that must open without migrating again (re-running
  // the migrations would fail).
  const auto files = MigrationFiles();
  for (size_t k = 1; k <= files.size(); ++k) {
    SCOPED_TRACE(fmt::format("database at version {}", k));
    const std::string path = PathOf(fmt::format("version_{}.db", k));
    {
      RawConnection raw(path);
      raw.Exec("BEGIN");
      for (size_t i = 0; i < k; ++i) raw.Exec(ReadText(files[i]));
      raw.Exec(fmt::format("PRAGMA user_version = {}", k));
      raw.Exec("INSERT INTO meta (key, value) VALUES ('made_at_version', '" +
               std::to_string(k) + "')");
      raw.Exec("COMMIT");
    }
    Database db(path);
    EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
    EXPECT_EQ(db.GetMeta("made_at_version"), std::to_string(k));
    const Sample sample = WriteSample(&db, 7);
    ExpectSample(sample, db);
  }
}

TEST_F(DatabaseFileTest, FailedMigrationLeavesTheFileUnchanged) {
  // A version-0 file holding a table of another program: never add epiloc's
  // tables to it.
  const std::string path = PathOf("other.db");
  {
    RawConnection raw(path);
    raw.Exec("CREATE TABLE photos (id INTEGER PRIMARY KEY)");
  }
  ExpectError([&] { Database db(path); }, {path, "not an epiloc one"});
  // Issue 18 item 12: the other program's file is not switched to WAL, no -wal/-shm beside it.
  EXPECT_FALSE(fs::exists(path + "-wal"));
  EXPECT_FALSE(fs::exists(path + "-shm"));
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"), 0);
  EXPECT_EQ(raw.QueryInt("SELECT count(*) FROM sqlite_schema"), 1);
  EXPECT_EQ(raw.QueryText("PRAGMA journal_mode"), "delete");
}

TEST_F(DatabaseFileTest, NotADatabaseLeavesNoFilesBeside) {
  const std::string path = PathOf("notes.txt");
  { std::ofstream(path) << "just some text, long enough to be read as a header............\n"; }
  ExpectError([&] { Database db(path); }, {path, "not an SQLite database"});
  ExpectError([&] { Database db(path, Database::Mode::kReadOnly); }, {path});
  EXPECT_FALSE(fs::exists(path + "-wal"));
  EXPECT_FALSE(fs::exists(path + "-shm"));
  EXPECT_FALSE(fs::exists(path + "-journal"));
}

// Runs `check` in a child process that sees `dir` read-only (a read-only bind mount in a private
// mount namespace when run as root, whom permissions do not stop; else chmod 0555). Returns the
// child's exit code, or -1 when the read-only view cannot be set up (the test is skipped).
int RunWithReadOnlyFolder(const fs::path& dir, const std::function<int()>& check) {
  const bool root = ::geteuid() == 0;
  if (!root) fs::permissions(dir, fs::perms(0555));
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (root) {
      if (::unshare(CLONE_NEWNS) != 0 ||
          ::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0 ||
          ::mount(dir.c_str(), dir.c_str(), nullptr, MS_BIND, nullptr) != 0 ||
          ::mount(nullptr, dir.c_str(), nullptr, MS_BIND | MS_REMOUNT | MS_RDONLY, nullptr) != 0) {
        ::_exit(77);
      }
    }
    int code = 0;
    try {
      code = check();
    } catch (...) {
      code = 99;
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (!root) fs::permissions(dir, fs::perms(0755));
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 98;
  return code == 77 ? -1 : code;
}

TEST_F(DatabaseFileTest, ReadsADatabaseOnReadOnlyMedia) {
  // Issue 18 item 7: reading failed with "attempt to write a readonly database" (a WAL reader
  // creates <db>-shm beside the file).
  const fs::path media = dir_ / "media";
  fs::create_directories(media);
  const std::string path = (media / "route.sqlite").string();
  Sample sample;
  {
    Database db(path);
    sample = WriteSample(&db, 3);
  }
  ASSERT_FALSE(fs::exists(path + "-shm"));
  const int code = RunWithReadOnlyFolder(media, [&] {
    try {
      const Database db(path, Database::Mode::kReadOnly);
      if (db.NumFrames() != static_cast<int64_t>(sample.frames.size())) return 1;
    } catch (const Error& e) {
      std::fprintf(stderr, "read-only open: %s\n", e.what());
      return 2;
    }
    try {
      Database db(path);
      return 3;  // a write open must be refused
    } catch (const Error& e) {
      const std::string message = e.what();
      if (message.find("read-only") == std::string::npos ||
          message.find("writes to it") == std::string::npos) {
        std::fprintf(stderr, "write open: %s\n", e.what());
        return 4;
      }
    }
    return 0;
  });
  if (code < 0) GTEST_SKIP() << "cannot make a read-only folder here";
  EXPECT_EQ(code, 0);
}

TEST_F(DatabaseFileTest, RefusesANewerSchemaVersion) {
  const std::string path = PathOf("newer.db");
  {
    Database db(path);
    db.SetMeta("k", "v");
  }
  {
    RawConnection raw(path);
    raw.Exec("PRAGMA user_version = 999");
  }
  const std::string message = fmt::format(
      "{}: database schema version 999 is newer than this epiloc ({}); "
      "upgrade epiloc",
      path, Database::LatestSchemaVersion());
  ExpectError([&] { Database db(path); }, {message});
  ExpectError([&] { Database db(path, Database::Mode::kReadOnly); }, {message});
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"), 999);
}

TEST_F(DatabaseFileTest, RefusesAFileThatIsNotSqlite) {
  const std::string path = PathOf("notes.db");
  {
    std::ofstream out(path);
    for (int i = 0; i < 100; ++i)
      out << "this is a text file, not a database\n";
  }
  ExpectError([&] { Database db(path); }, {path, "not an SQLite database"});
  ExpectError([&] { Database db(path, Database::Mode::kReadOnly); },
              {path, "not an SQLite database"});
  EXPECT_THAT(ReadText(path), HasSubstr("this is a text file"));
}

TEST_F(DatabaseFileTest, CannotCreateInAMissingDirectory) {
  const std::string path = PathOf("no/such/dir/route.db");
  ExpectError([&] { Database db(path); }, {path, "unable to open"});
}

TEST_F(DatabaseFileTest, LockedDatabaseFailsQuicklyWithAClearMessage) {
  const std::string path = PathOf("locked.db");
  Database db(path);
  db.SetMeta("k", "before");
  RawConnection other(path);
  other.Exec("BEGIN IMMEDIATE");
  other.Exec("INSERT INTO meta (key, value) VALUES ('other', 'writer')");

  const auto start = std::chrono::steady_clock::now();
  ExpectError([&] { db.SetMeta("k", "during"); },
              {path + ": database is locked by another process"});
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  EXPECT_GT(seconds, 1.0);  // waited for the busy timeout
  EXPECT_LT(seconds, 5.0);  // but did not hang
  ExpectError([&] { Database::Transaction transaction(db); },
              {"locked by another process"});
  std::mt19937 rng(8);
  DbFrame frame;
  frame.drive_id = 1;
  frame.frame = 0;
  ExpectError(
      [&] {
        db.WriteFrame(frame, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"locked by another process"});

  // Reading is not blocked by the other writer (write-ahead log), and nor is
  // opening.
  EXPECT_EQ(db.GetMeta("k"), "before");
  EXPECT_FALSE(db.GetMeta("other").has_value());
  {
    Database second(path);
    EXPECT_EQ(second.GetMeta("k"), "before");
  }
  other.Exec("COMMIT");
  db.SetMeta("k", "after");
  EXPECT_EQ(db.GetMeta("k"), "after");
  EXPECT_EQ(db.GetMeta("other"), "writer");
}

// The names of the files beside `path` (its -wal, -shm, -journal), space-separated.
std::string FilesBeside(const std::string& path) {
  std::string text;
  for (const char* suffix : {"-wal", "-shm", "-journal"}) {
    if (fs::exists(path + suffix)) text += (text.empty() ? "" : " ") + path + suffix;
  }
  return text;
}

// Issue 18 (leftovers): a reader left empty <db>-wal and <db>-shm files beside a WAL-mode
// database (SQLite keeps them when the last connection to close is read-only).
TEST_F(DatabaseFileTest, ReaderLeavesNoFilesBeside) {
  const std::string path = PathOf("route.db");
  Sample sample;
  {
    Database db(path);
    sample = WriteSample(&db, 5);
  }
  EXPECT_EQ(FilesBeside(path), "");
  {
    const Database db(path, Database::Mode::kReadOnly);
    ExpectSample(sample, db);
  }
  EXPECT_EQ(FilesBeside(path), "");
}

// A reader during a write: both work (WAL while a writer is open); the writer closing first
// cannot leave WAL mode under the reader and does not wait for it; the next writer to close
// leaves the folder clean again.
TEST_F(DatabaseFileTest, ReaderDuringAWriteAndAfterIt) {
  const std::string path = PathOf("route.db");
  {
    Database db(path);
    db.SetMeta("k", "first");
  }
  auto writer = std::make_unique<Database>(path);
  const Database reader(path, Database::Mode::kReadOnly);
  EXPECT_EQ(reader.GetMeta("k"), "first");
  writer->SetMeta("k", "second");
  EXPECT_EQ(reader.GetMeta("k"), "second");
  const auto start = std::chrono::steady_clock::now();
  writer.reset();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
  EXPECT_EQ(reader.GetMeta("k"), "second");
  {
    Database again(path);
    EXPECT_EQ(again.GetMeta("k"), "second");
  }
  EXPECT_EQ(reader.GetMeta("k"), "second");
}

TEST_F(DatabaseFileTest, ReadOnlyModeReadsAndNeverWrites) {
  const std::string missing = PathOf("missing.db");
  ExpectError([&] { Database db(missing, Database::Mode::kReadOnly); },
              {missing});
  EXPECT_FALSE(fs::exists(missing));

  const std::string empty = PathOf("empty.db");
  { RawConnection raw(empty); }
  ExpectError([&] { Database db(empty, Database::Mode::kReadOnly); },
              {empty, "not an epiloc database"});

  const std::string path = PathOf("route.db");
  Sample sample;
  {
    Database db(path);
    sample = WriteSample(&db, 9);
  }
  Database db(path, Database::Mode::kReadOnly);
  ExpectSample(sample, db);
  ExpectError([&] { db.SetMeta("k", "v"); }, {path, "readonly"});
  ExpectError([&] { db.WriteRoute({}); }, {path, "readonly"});
  EXPECT_EQ(db.ReadRoute(), sample.route);
}

TEST_F(DatabaseFileTest, RetrievalModelAndGlobalDescriptorsRoundTrip) {
  const std::string path = PathOf("retrieval.db");
  Sample sample;
  const std::vector<uint8_t> model = {'E', 'G', 'D', 'M', 0, 255, 7};
  // Every float bit pattern that is finite survives, including -0 and denormals.
  const std::vector<float> first = {1.0f, -0.0f, 1e-40f, -3.25e38f};
  const std::vector<float> second = {0.5f, 0.25f, -0.125f, 2.0f};
  {
    Database db(path);
    sample = WriteSample(&db, 11);
    EXPECT_FALSE(db.ReadRetrievalModel().has_value());
    EXPECT_TRUE(db.ReadGlobalDescriptors().empty());
    db.WriteRetrievalModel({1, 2, 3}, 8, 4);
    db.WriteRetrievalModel(model, 64, 4);  // replaces
    db.WriteGlobalDescriptor(sample.frames[2].frame.image_id, second);
    db.WriteGlobalDescriptor(sample.frames[0].frame.image_id, second);
    db.WriteGlobalDescriptor(sample.frames[0].frame.image_id, first);  // replaces
    ExpectError([&] { db.WriteGlobalDescriptor(sample.frames[1].frame.image_id, {}); },
                {path, "empty global descriptor"});
    ExpectError(
        [&] {
          db.WriteGlobalDescriptor(sample.frames[1].frame.image_id,
                                   {std::numeric_limits<float>::quiet_NaN()});
        },
        {path, "non-finite"});
    ExpectError([&] { db.WriteGlobalDescriptor(999, first); }, {path, "FOREIGN KEY"});
  }
  {
    Database db(path, Database::Mode::kReadOnly);
    EXPECT_EQ(db.ReadRetrievalModel(), model);
    EXPECT_EQ(db.NumGlobalDescriptors(), 2);
    const auto descriptors = db.ReadGlobalDescriptors();
    ASSERT_EQ(descriptors.size(), 2u);
    EXPECT_EQ(descriptors[0].first, sample.frames[0].frame.image_id);
    EXPECT_EQ(descriptors[1].first, sample.frames[2].frame.image_id);
    ASSERT_EQ(descriptors[0].second.size(), first.size());
    for (size_t i = 0; i < first.size(); ++i) {
      EXPECT_EQ(std::memcmp(&descriptors[0].second[i], &first[i], 4), 0) << i;
    }
    EXPECT_EQ(descriptors[1].second, second);
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryText("SELECT num_words || ' ' || dims FROM retrieval_model"), "64 4");
  // Little-endian float32: 1.0f is 00 00 80 3F.
  EXPECT_EQ(raw.QueryText("SELECT hex(substr(data, 1, 4)) FROM global_descriptors "
                          "ORDER BY image_id LIMIT 1"),
            "0000803F");
  raw.Exec("PRAGMA ignore_check_constraints = ON");
  raw.Exec("UPDATE global_descriptors SET dims = 5");
  {
    Database db(path);
    ExpectError([&] { db.ReadGlobalDescriptors(); },
                {path, "corrupt global descriptor blob for image"});
    // Deleting a frame deletes its descriptor; clearing deletes the rest.
    db.DeleteFrame(sample.frames[0].frame.image_id);
    EXPECT_EQ(db.NumGlobalDescriptors(), 1);
    db.ClearGlobalDescriptors();
    EXPECT_EQ(db.NumGlobalDescriptors(), 0);
    db.DeleteRetrievalModel();
    EXPECT_FALSE(db.ReadRetrievalModel().has_value());
  }
}

TEST_F(DatabaseFileTest, MigratingAVersionOneDatabaseKeepsItsFramesAndAddsRetrieval) {
  const auto files = MigrationFiles();
  ASSERT_GE(files.size(), 2u);
  const std::string path = PathOf("version_1.db");
  {
    // As epiloc 0.x left it: schema version 1 with a drive and a frame.
    RawConnection raw(path);
    raw.Exec("BEGIN");
    raw.Exec(ReadText(files[0]));
    raw.Exec("PRAGMA user_version = 1");
    raw.Exec("INSERT INTO drives (drive_id, name) VALUES (1, 'old')");
    raw.Exec(
        "INSERT INTO frames (image_id, drive_id, frame, timestamp_s, lat_deg, lon_deg, alt_m, "
        "e_m, n_m, u_m, heading_deg, s_m, num_features) "
        "VALUES (7, 1, 3, 12.5, 49.0, 8.4, 110.0, 1.0, 2.0, 3.0, 90.0, 4.5, 1)");
    raw.Exec("INSERT INTO keypoints VALUES (7, 1, 4, zeroblob(16))");
    raw.Exec("INSERT INTO descriptors VALUES (7, 1, 128, zeroblob(128))");
    raw.Exec("COMMIT");
  }
  {
    Database db(path);
    EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
    const auto frames = db.ReadFrames();
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].image_id, 7);
    EXPECT_EQ(frames[0].frame, 3);
    EXPECT_EQ(frames[0].s_m, 4.5);
    EXPECT_EQ(db.ReadDescriptors(7).rows(), 1);
    EXPECT_FALSE(db.ReadRetrievalModel().has_value());
    EXPECT_EQ(db.NumGlobalDescriptors(), 0);
    db.WriteGlobalDescriptor(7, {1.0f, 0.0f});
    db.WriteRetrievalModel({1, 2}, 2, 2);
    EXPECT_EQ(db.NumPoints(), 0);  // schema 3: no structure yet
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"), Database::LatestSchemaVersion());
  EXPECT_EQ(raw.QueryInt("SELECT count(*) FROM global_descriptors"), 1);
  EXPECT_EQ(raw.QueryInt("SELECT count(*) FROM frames"), 1);
}

}  // namespace
}  // namespace epiloc
