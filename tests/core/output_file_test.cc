#include "epiloc/core/output_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

size_t NumEntries(const std::string& dir) {
  size_t n = 0;
  for (const auto& entry : fs::directory_iterator(dir)) n += entry.exists() ? 1 : 0;
  return n;
}

TEST(SameFile, ResolvesSpellingsAndLinks) {
  TempDir dir;
  WriteText(dir / "route.sqlite", "x");
  fs::create_directories(dir / "sub");
  EXPECT_TRUE(SameFile(dir / "route.sqlite", dir / "sub/../route.sqlite"));
  EXPECT_TRUE(SameFile(dir / "route.sqlite", dir / "./route.sqlite"));
  fs::create_symlink(dir / "route.sqlite", dir / "link.sqlite");
  EXPECT_TRUE(SameFile(dir / "link.sqlite", dir / "route.sqlite"));
  fs::create_hard_link(dir / "route.sqlite", dir / "hard.sqlite");
  EXPECT_TRUE(SameFile(dir / "hard.sqlite", dir / "route.sqlite"));
  // Not yet existing: compared by path.
  EXPECT_TRUE(SameFile(dir / "new.csv", dir / "sub/../new.csv"));
  EXPECT_FALSE(SameFile(dir / "new.csv", dir / "route.sqlite"));
  EXPECT_FALSE(SameFile("", dir / "route.sqlite"));
}

TEST(CheckOutputs, RefusesAnOutputThatIsAnInput) {
  TempDir dir;
  WriteText(dir / "R.sqlite", "database");
  const std::string message = ErrorOf([&] {
    CheckOutputs({{"--out", dir / "./R.sqlite"}}, {{"--db", dir / "R.sqlite"}});
  });
  EXPECT_THAT(message, ::testing::HasSubstr("--out " + dir / "./R.sqlite"));
  EXPECT_THAT(message, ::testing::HasSubstr("input --db " + dir / "R.sqlite"));
  EXPECT_EQ(ReadAll(dir / "R.sqlite"), "database");
  // Two outputs on one file.
  ExpectError([&] { CheckOutputs({{"--out", dir / "a.csv"}, {"--geojson", dir / "a.csv"}}, {}); },
              {"--geojson", "--out"});
  // Standard output and absent options are not files.
  CheckOutputs({{"--out", "-"}, {"--nmea-out", "-"}, {"--geojson", ""}},
               {{"--db", dir / "R.sqlite"}});
  CheckOutputs({{"--out", dir / "result.csv"}}, {{"--db", dir / "R.sqlite"}});
  EXPECT_FALSE(fs::exists(dir / "result.csv"));
  EXPECT_EQ(NumEntries(dir.str()), 1u);  // the probe file is gone
}

TEST(CheckOutputs, UnwritableOutputsAreFoundBeforeTheWork) {
  TempDir dir;
  ExpectError([&] { CheckOutputs({{"--geojson", dir / "missing/x.geojson"}}, {}); },
              {"--geojson", "missing", "does not exist"});
  ExpectError([&] { CheckOutputs({{"--out", dir.str()}}, {}); }, {"--out", "is a folder"});
  WriteText(dir / "file", "");
  ExpectError([&] { CheckOutputs({{"--json", dir / "file/x.json"}}, {}); }, {"--json"});
}

TEST(AtomicFile, CommitReplacesDiscardKeeps) {
  TempDir dir;
  WriteText(dir / "out.png", "old");
  {
    AtomicFile file(dir / "out.png");
    EXPECT_EQ(fs::path(file.temp_path()).extension(), ".png");
    EXPECT_EQ(fs::path(file.temp_path()).parent_path(), fs::path(dir.str()));
    WriteText(file.temp_path(), "new");
    EXPECT_EQ(ReadAll(dir / "out.png"), "old");
  }  // not committed
  EXPECT_EQ(ReadAll(dir / "out.png"), "old");
  EXPECT_EQ(NumEntries(dir.str()), 1u);
  {
    AtomicOfstream out(dir / "out.png");
    out << "new";
    out.Commit();
  }
  EXPECT_EQ(ReadAll(dir / "out.png"), "new");
  EXPECT_EQ(NumEntries(dir.str()), 1u);
}

// Issue 18 (unseen inputs): `--out /dev/full` as root renamed the temporary file over the device
// node, leaving a regular file at /dev/full. A FIFO stands in for a device here: it must stay a
// FIFO and its reader must get the rows.
TEST(AtomicFile, ADeviceOrFifoIsWrittenInPlaceNotReplaced) {
  TempDir dir;
  const std::string pipe = dir / "pipe";
  ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0);
  const int reader = ::open(pipe.c_str(), O_RDONLY | O_NONBLOCK);  // so the writer's open returns
  ASSERT_GE(reader, 0);
  CheckOutputs({{"--out", pipe}}, {});
  {
    CsvWriter csv(pipe, {"a"});
    csv.WriteRow({"1"});
    csv.Close();
  }
  std::string received(64, '\0');
  const ssize_t n = ::read(reader, received.data(), received.size());
  ::close(reader);
  ASSERT_GT(n, 0);
  received.resize(static_cast<size_t>(n));
  EXPECT_EQ(received, "a\n1\n");
  EXPECT_TRUE(fs::is_fifo(fs::symlink_status(pipe)));
  EXPECT_EQ(NumEntries(dir.str()), 1u);  // no temporary file beside it
}

TEST(AtomicFile, AFailedWriteToADeviceIsAnError) {
  if (!fs::is_character_file("/dev/full")) GTEST_SKIP() << "no /dev/full";
  AtomicOfstream out("/dev/full");
  for (int i = 0; i < 100000; ++i) out << "0123456789";
  ExpectError([&] { out.Commit(); }, {"/dev/full", "write failed"});
  EXPECT_TRUE(fs::is_character_file(fs::symlink_status("/dev/full")));
}

// Issue 18 (unseen inputs): `export --out -` wrote a file named "-" (the checks had skipped "-"
// as standard output) and exited 0.
TEST(AtomicFile, StandardOutputIsNotAFileName) {
  TempDir dir;
  const fs::path previous = fs::current_path();
  fs::current_path(dir.str());
  ExpectError([] { AtomicOfstream out("-"); }, {"-", "standard output"});
  EXPECT_FALSE(fs::exists(dir / "-"));
  fs::current_path(previous);
}

TEST(AtomicFile, ALinkStaysALink) {
  TempDir dir;
  fs::create_directories(dir / "real");
  WriteText(dir / "real/out.csv", "old");
  fs::create_symlink(dir / "real/out.csv", dir / "link.csv");
  {
    AtomicOfstream out(dir / "link.csv");
    out << "new";
    out.Commit();
  }
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir / "link.csv")));
  EXPECT_EQ(ReadAll(dir / "real/out.csv"), "new");
}

// Issue 18 (unseen inputs): `localize` killed by SIGTERM or Ctrl-C left ".r.csv.tmp-<pid>-<n>.csv"
// beside its outputs.
TEST(AtomicFileDeathTest, ASignalRemovesTheTemporaryFiles) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  TempDir dir;
  for (const int signal_number : {SIGTERM, SIGINT}) {
    EXPECT_EXIT(
        {
          CsvWriter csv(dir / "r.csv", {"a"});
          csv.WriteRow({"1"});
          csv.Flush();
          AtomicOfstream nmea(dir / "r.nmea");
          nmea << "$GPGGA";
          nmea.stream().flush();
          if (NumEntries(dir.str()) != 2) std::_Exit(3);  // both temporaries exist
          std::raise(signal_number);
          std::_Exit(4);
        },
        ::testing::KilledBySignal(signal_number), "");
    EXPECT_EQ(NumEntries(dir.str()), 0u);
  }
}

TEST(CsvWriterAtomic, AFailedRunLeavesNoPartialFile) {
  TempDir dir;
  WriteText(dir / "previous.csv", "a\n1\n");
  try {
    CsvWriter csv(dir / "previous.csv", {"a"});
    csv.WriteRow({"2"});
    csv.Flush();
    EXPECT_EQ(ReadAll(dir / "previous.csv"), "a\n1\n");  // not visible until closed
    throw Error("disk full");
  } catch (const Error&) {
  }
  EXPECT_EQ(ReadAll(dir / "previous.csv"), "a\n1\n");
  try {
    CsvWriter csv(dir / "fresh.csv", {"a"});
    csv.WriteRow({"2"});
    throw Error("later failure");
  } catch (const Error&) {
  }
  EXPECT_FALSE(fs::exists(dir / "fresh.csv"));
  EXPECT_EQ(NumEntries(dir.str()), 1u);
  {
    CsvWriter csv(dir / "fresh.csv", {"a"});
    csv.WriteRow({"3"});
  }  // a normal end commits
  EXPECT_EQ(ReadAll(dir / "fresh.csv"), "a\n3\n");
}

}  // namespace
}  // namespace epiloc
