// Bad input to `epiloc build-db`, end to end through the binary: one line on stderr naming the
// file (and line), exit code 1, and an existing database left exactly as it was.
#include <sqlite3.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "epiloc/core/error.h"
#include "epiloc/survey/build_db.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct RunResult {
  int exit_code = -1;
  std::string stderr_text;
};

RunResult RunEpiloc(const std::string& args) {
  const std::string command = fmt::format("{} {} 2>&1 1>/dev/null", EPILOC_BINARY, args);
  RunResult result;
  FILE* pipe = popen(command.c_str(), "r");
  std::array<char, 4096> buffer{};
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.stderr_text += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

int NumLines(const std::string& text) {
  int lines = 0;
  for (const char c : text) lines += c == '\n';
  return lines;
}

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

// The names in `dir` starting with `prefix`, sorted, space-separated.
std::string Listing(const fs::path& dir, const std::string& prefix = "") {
  std::vector<std::string> names;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) == 0) names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  std::string text;
  for (const std::string& name : names) text += (text.empty() ? "" : " ") + name;
  return text;
}

// Everything a test needs to compare a database before and after: row counts and integrity.
std::string Snapshot(const fs::path& db_path) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  std::string text;
  for (const char* sql :
       {"SELECT count(*) FROM frames", "SELECT group_concat(name) FROM drives",
        "SELECT count(*) FROM keypoints", "SELECT count(*) FROM route_points",
        "SELECT count(*) FROM cameras", "SELECT group_concat(key || '=' || value) FROM meta",
        "PRAGMA integrity_check"}) {
    sqlite3_stmt* stmt = nullptr;
    sqlite3_prepare_v2(db, sql, -1, &stmt, nullptr);
    if (sqlite3_step(stmt) == SQLITE_ROW && sqlite3_column_text(stmt, 0) != nullptr) {
      text += reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
    }
    text += ";";
    sqlite3_finalize(stmt);
  }
  sqlite3_close(db);
  return text;
}

class BuildDbErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            fmt::format("epiloc_build_db_errors_{}_{}", ::getpid(),
                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
    db_ = root_ / "route.sqlite";
    MakeDrive(root_ / "good", "good");
    const RunResult result = RunEpiloc(
        fmt::format("build-db --quiet --drive {} --db {}", (root_ / "good").string(), db_.string()));
    ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
    before_ = Snapshot(db_);
  }
  void TearDown() override {
    if (std::getenv("EPILOC_KEEP_TEST_FILES") == nullptr) fs::remove_all(root_);
  }

  // A drive of kFrames textured 320x240 frames driving north at 5 m/s with GNSS at 10 Hz.
  static void MakeDrive(const fs::path& dir, const std::string& name) {
    fs::create_directories(dir / "images");
    std::mt19937 rng(42);
    std::uniform_int_distribution<int> x(0, 319), y(0, 239), r(2, 10), v(0, 255);
    std::string frames = "frame,timestamp_s,image\n";
    for (int i = 0; i < kFrames; ++i) {
      cv::Mat image(240, 320, CV_8UC1, cv::Scalar(128));
      for (int k = 0; k < 400; ++k) {
        cv::circle(image, cv::Point(x(rng), y(rng)), r(rng), cv::Scalar(v(rng)), cv::FILLED);
      }
      const std::string file = fmt::format("images/{:04d}.png", i);
      cv::imwrite((dir / file).string(), image);
      frames += fmt::format("{},{:.3f},{}\n", i, 100.0 + 0.1 * i, file);
    }
    WriteText(dir / "frames.csv", frames);
    std::string gnss = "timestamp_s,lat_deg,lon_deg,alt_m\n";
    for (int i = 0; i < kFrames + 2; ++i) {
      gnss += fmt::format("{:.3f},{:.9f},8.4,110.0\n", 99.95 + 0.1 * i, 49.0 + 0.5 * i / 111200.0);
    }
    WriteText(dir / "gnss.csv", gnss);
    WriteManifest(dir, name, R"("fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240)",
                  R"({"file": "gnss.csv", "format": "csv"})");
  }

  static void WriteManifest(const fs::path& dir,
                            const std::string& name,
                            const std::string& camera,
                            const std::string& gnss) {
    WriteText(dir / "drive.json",
              fmt::format(R"({{"epiloc_drive": 1, "name": "{}", "camera": {{{}}},
  "frames": {{"csv": "frames.csv"}}, "gnss": {}, "max_gap_s": 0.5}})",
                          name, camera, gnss));
  }

  // Copies the good drive under a new name, for one test to break.
  fs::path CopyDrive(const std::string& name) {
    const fs::path dir = root_ / name;
    fs::copy(root_ / "good", dir, fs::copy_options::recursive);
    std::ifstream in(dir / "drive.json");
    std::string manifest((std::istreambuf_iterator<char>(in)), {});
    manifest.replace(manifest.find("\"good\""), 6, "\"" + name + "\"");
    WriteText(dir / "drive.json", manifest);
    return dir;
  }

  static void ReplaceLine(const fs::path& file, int line_number, const std::string& text) {
    std::ifstream in(file);
    std::string line, out;
    for (int n = 1; std::getline(in, line); ++n) out += (n == line_number ? text : line) + "\n";
    in.close();
    WriteText(file, out);
  }

  // Runs build-db on `drive` into the shared database and checks the failure contract.
  void ExpectFailure(const fs::path& drive, const std::string& expected_in_message) {
    const RunResult result = RunEpiloc(
        fmt::format("build-db --quiet --drive {} --db {}", drive.string(), db_.string()));
    EXPECT_EQ(result.exit_code, 1) << result.stderr_text;
    EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
    EXPECT_THAT(result.stderr_text, HasSubstr("epiloc build-db: error: "));
    EXPECT_THAT(result.stderr_text, HasSubstr(expected_in_message));
    EXPECT_EQ(Snapshot(db_), before_) << "the database changed";
    EXPECT_EQ(Listing(root_, "route.sqlite"), "route.sqlite") << "files left beside the database";
  }

  static constexpr int kFrames = 6;
  fs::path root_;
  fs::path db_;
  std::string before_;
};

TEST_F(BuildDbErrors, MissingImage) {
  const fs::path drive = CopyDrive("missing_image");
  fs::remove(drive / "images/0003.png");
  ExpectFailure(drive, "0003.png");
}

TEST_F(BuildDbErrors, CorruptImageFoundHalfWayIsUndone) {
  const fs::path drive = CopyDrive("corrupt_image");
  WriteText(drive / "images/0004.png", "this is not a PNG file");
  ExpectFailure(drive, "0004.png");
}

// Issue 18 item 10: a truncated PNG is one line naming the frames.csv line and the image as listed
// there, whether it is the first frame (checked when the drive is loaded), one found half-way
// through the survey, or a query frame.
TEST_F(BuildDbErrors, TruncatedImageNamesTheFramesCsvLine) {
  const auto truncate = [](const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    in.close();
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes.substr(0, bytes.size() / 2);
  };
  const fs::path survey = CopyDrive("truncated_survey");
  truncate(survey / "images/0004.png");
  ExpectFailure(survey, (survey / "frames.csv").string() +
                            ":6: image images/0004.png: cannot decode (truncated PNG: ");
  const fs::path first = CopyDrive("truncated_first");
  truncate(first / "images/0000.png");
  ExpectFailure(first, (first / "frames.csv").string() +
                           ":2: image images/0000.png: cannot decode (truncated PNG: ");

  const RunResult query =
      RunEpiloc(fmt::format("localize --refine none --db {} --drive {} --out {}", db_.string(),
                            survey.string(), (root_ / "query.csv").string()));
  EXPECT_EQ(query.exit_code, 1) << query.stderr_text;
  EXPECT_EQ(NumLines(query.stderr_text), 1) << query.stderr_text;
  EXPECT_THAT(query.stderr_text,
              HasSubstr("epiloc localize: error: " + (survey / "frames.csv").string() +
                        ":6: image images/0004.png: cannot decode (truncated PNG: "));
  EXPECT_FALSE(fs::exists(root_ / "query.csv"));
}

// Issue 18 (leftovers): a failed first build left an empty database with its -wal and -shm
// files; a later build-db then resumed into a database that had never held anything.
TEST_F(BuildDbErrors, FailedFirstBuildLeavesNoDatabase) {
  const fs::path corrupt = CopyDrive("first_corrupt");
  WriteText(corrupt / "images/0004.png", "this is not a PNG file");
  const fs::path missing = CopyDrive("first_missing");
  for (int i = 1; i < kFrames; ++i) fs::remove(missing / fmt::format("images/{:04d}.png", i));
  for (const auto& [drive, message] :
       {std::pair<fs::path, std::string>{corrupt, "0004.png"}, {missing, "0001.png"}}) {
    SCOPED_TRACE(drive.string());
    const fs::path folder = root_ / ("new_" + drive.filename().string());
    fs::create_directories(folder);
    const RunResult result = RunEpiloc(fmt::format(
        "build-db --quiet --drive {} --db {}", drive.string(), (folder / "route.sqlite").string()));
    EXPECT_EQ(result.exit_code, 1) << result.stderr_text;
    EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
    EXPECT_THAT(result.stderr_text, HasSubstr(message));
    EXPECT_EQ(Listing(folder), "") << "a failed first build left files";
  }
}

// Issue 18 (leftovers): commands that only read the database left empty <db>-wal and <db>-shm
// files beside it (SQLite keeps them when the last connection to close is read-only).
TEST_F(BuildDbErrors, ReadingCommandsLeaveTheDatabaseFolderAsTheyFoundIt) {
  ASSERT_EQ(Listing(root_, "route.sqlite"), "route.sqlite");
  const fs::path out = root_ / "out";
  fs::create_directories(out);
  for (const std::string& args :
       {fmt::format("info --db {}", db_.string()),
        fmt::format("localize --db {} --drive {} --out {}", db_.string(), (root_ / "good").string(),
                    (out / "result.csv").string())}) {
    SCOPED_TRACE(args);
    const RunResult result = RunEpiloc(args);
    EXPECT_EQ(result.exit_code, 0) << result.stderr_text;
    EXPECT_EQ(Listing(root_, "route.sqlite"), "route.sqlite");
  }
  // A later build still adds to it.
  const RunResult second =
      RunEpiloc(fmt::format("build-db --quiet --no-triangulate --drive {} --db {}",
                            CopyDrive("second").string(), db_.string()));
  EXPECT_EQ(second.exit_code, 0) << second.stderr_text;
  EXPECT_THAT(Snapshot(db_), HasSubstr("good,second;"));
  EXPECT_EQ(Listing(root_, "route.sqlite"), "route.sqlite");
}

TEST_F(BuildDbErrors, MalformedCsvLine) {
  const fs::path drive = CopyDrive("bad_csv");
  ReplaceLine(drive / "gnss.csv", 4, "100.25,forty-nine,8.4,110.0");
  ExpectFailure(drive, "gnss.csv:4");
}

TEST_F(BuildDbErrors, MalformedNmeaLine) {
  const fs::path drive = CopyDrive("bad_nmea");
  WriteText(drive / "gnss.nmea",
            "$GPRMC,000140.00,A,4900.0000,N,00824.0000,E,0.0,0.0,010170,,,A*5F\n"
            "$GPGGA,000140.00,4900.0000,N,00824.0000,E,1,08,0.9,110.0,M,47.0,M,,*FF\n");
  WriteManifest(drive, "bad_nmea",
                R"("fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240)",
                R"({"file": "gnss.nmea", "format": "nmea"})");
  ExpectFailure(drive, "gnss.nmea:2");
}

TEST_F(BuildDbErrors, TimestampsGoingBackwards) {
  const fs::path drive = CopyDrive("backwards");
  ReplaceLine(drive / "frames.csv", 5, "3,100.05,images/0003.png");
  ExpectFailure(drive, "frames.csv:5");
}

TEST_F(BuildDbErrors, CalibrationMissing) {
  const fs::path drive = CopyDrive("no_fx");
  WriteManifest(drive, "no_fx", R"("fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240)",
                R"({"file": "gnss.csv", "format": "csv"})");
  ExpectFailure(drive, "drive.json");
}

TEST_F(BuildDbErrors, CalibrationInconsistentWithImageSize) {
  const fs::path drive = CopyDrive("wrong_size");
  WriteManifest(drive, "wrong_size",
                R"("fx": 600, "fy": 600, "cx": 320, "cy": 240, "width": 640, "height": 480)",
                R"({"file": "gnss.csv", "format": "csv"})");
  ExpectFailure(drive, "0000.png");
}

// Issue 18 item 11: absurd values that used to pass (and gave 0 features without a word).
TEST_F(BuildDbErrors, AbsurdCalibrationIsRefused) {
  const std::string gnss = R"({"file": "gnss.csv", "format": "csv"})";
  const struct {
    const char* name;
    const char* camera;
    const char* message;
  } cases[] = {
      {"fx_tiny", R"("fx": 1e-300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240)",
       "focal length"},
      {"fx_huge", R"("fx": 1e300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240)",
       "focal length"},
      {"k1_huge",
       R"("fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240, "distortion": [1e10, 0, 0, 0, 0])",
       "k1"},
      // Issue 18 (leftovers): each coefficient within its bound, the model not invertible.
      {"k1_k2_fold",
       R"("fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240, "distortion": [50, -300, 0, 0, 0])",
       "camera: distortion k1=50 k2=-300 k3=0 is not invertible over the image"},
      {"k1_stretch",
       R"("fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240, "distortion": [50, 0, 0, 0, 0])",
       "stretches the image"},
      {"fy_20_fx", R"("fx": 300, "fy": 6000, "cx": 160, "cy": 120, "width": 320, "height": 240)",
       "camera: fy / fx = 20 "},
      {"width_wraps",
       R"("fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 4294967297, "height": 240)",
       "camera.width"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path drive = CopyDrive(c.name);
    WriteManifest(drive, c.name, c.camera, gnss);
    ExpectFailure(drive, "drive.json");
    ExpectFailure(drive, c.message);
  }
}

TEST_F(BuildDbErrors, AltitudeOutOfRange) {
  const fs::path drive = CopyDrive("bad_alt");
  ReplaceLine(drive / "gnss.csv", 3, "100.05,49.0,8.4,1e300");
  ExpectFailure(drive, "gnss.csv:3: altitude");
}

TEST_F(BuildDbErrors, FramesWithoutFeaturesAreWarnedAbout) {
  const fs::path drive = CopyDrive("black");
  for (const int i : {2, 3}) {
    cv::imwrite((drive / fmt::format("images/{:04d}.png", i)).string(),
                cv::Mat(240, 320, CV_8UC1, cv::Scalar(0)));
  }
  const RunResult result =
      RunEpiloc(fmt::format("build-db --quiet --no-triangulate --drive {} --db {}",
                            drive.string(), (root_ / "black.sqlite").string()));
  EXPECT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr("2 of 6 frames gave no SIFT features (frames 2, 3)"));
  const std::string csv = (drive / "frames.csv").string();
  EXPECT_THAT(result.stderr_text, HasSubstr(csv + ":4: frame 2 gave no SIFT features"));
  EXPECT_THAT(result.stderr_text, HasSubstr(csv + ":5: frame 3 gave no SIFT features"));
}

// Issue 18 item 11 for query frames: the first few featureless frames are named (with their
// frames.csv line), the rest only counted in one summary line, so a dark drive does not flood.
TEST_F(BuildDbErrors, QueryFramesWithoutFeaturesAreWarnedAbout) {
  const fs::path drive = CopyDrive("black_query");
  for (int i = 1; i < kFrames; ++i) {
    cv::imwrite((drive / fmt::format("images/{:04d}.png", i)).string(),
                cv::Mat(240, 320, CV_8UC1, cv::Scalar(0)));
  }
  const RunResult result =
      RunEpiloc(fmt::format("localize --db {} --drive {} --out {}", db_.string(), drive.string(),
                            (root_ / "black_query.csv").string()));
  EXPECT_EQ(result.exit_code, 0) << result.stderr_text;
  const std::string csv = (drive / "frames.csv").string();
  EXPECT_THAT(result.stderr_text, HasSubstr(csv + ":3: frame 1 gave no SIFT features"));
  EXPECT_THAT(result.stderr_text, HasSubstr(csv + ":5: frame 3 gave no SIFT features"));
  EXPECT_THAT(result.stderr_text, HasSubstr("further ones are counted at the end"));
  EXPECT_THAT(result.stderr_text, Not(HasSubstr("frame 4 gave")));
  EXPECT_THAT(result.stderr_text,
              HasSubstr("5 of 6 query frames gave no SIFT features (frames 1, 2, 3, 4, 5)"));
  int warnings = 0;
  for (size_t at = 0; (at = result.stderr_text.find("no SIFT features", at)) != std::string::npos;
       ++at) {
    ++warnings;
  }
  EXPECT_EQ(warnings, 4) << result.stderr_text;
}

// The same for frames read from a video: the warning names the video and the frame's index in it
// (a video has no frames CSV line to name).
TEST_F(BuildDbErrors, VideoFramesWithoutFeaturesNameTheVideo) {
  const std::string video = (root_ / "black.avi").string();
  {
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                           cv::Size(320, 240));
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < kFrames; ++i) {
      cv::Mat grey = cv::imread((root_ / fmt::format("good/images/{:04d}.png", i)).string(),
                                cv::IMREAD_GRAYSCALE);
      if (i == 2 || i == 4) grey.setTo(0);
      cv::Mat colour;
      cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
      writer.write(colour);
    }
  }
  const fs::path good = root_ / "good";
  const RunResult result = RunEpiloc(fmt::format(
      "localize --db {} --video {} --calibration {} --gnss {} --video-start-s 100 --out {}",
      db_.string(), video, (good / "drive.json").string(), (good / "gnss.csv").string(),
      (root_ / "black_video.csv").string()));
  EXPECT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr(video + " frame 2 gave no SIFT features"));
  EXPECT_THAT(result.stderr_text, HasSubstr(video + " frame 4 gave no SIFT features"));
  EXPECT_THAT(result.stderr_text, Not(HasSubstr("frame 3 gave")));
  EXPECT_THAT(result.stderr_text,
              HasSubstr("2 of 6 query frames gave no SIFT features (frames 2, 4)"));
}

// Issue 18 item 12: a second build of the same drive running at the same time was reported as
// "already in the database".
TEST_F(BuildDbErrors, ConcurrentBuildOfTheSameDriveIsNamed) {
  const fs::path drive = CopyDrive("concurrent");
  BuildDbOptions options;
  options.triangulate = false;
  options.num_threads = 1;
  bool other_ran = false;
  const std::string message = [&] {
    try {
      BuildDatabase(drive.string(), db_.string(), options, [&](int64_t done, int64_t total) {
        if (other_ran) return;
        other_ran = true;  // after our first frame: another process builds the whole drive
        const RunResult other = RunEpiloc(fmt::format(
            "build-db --quiet --no-triangulate --drive {} --db {}", drive.string(), db_.string()));
        EXPECT_EQ(other.exit_code, 0) << other.stderr_text;
      });
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  }();
  EXPECT_TRUE(other_ran);
  EXPECT_THAT(message, HasSubstr("another build of drive 'concurrent' is running"));
}

TEST_F(BuildDbErrors, IdenticalPositionsNameTheirFile) {
  const fs::path drive = CopyDrive("standing");
  std::string gnss = "timestamp_s,lat_deg,lon_deg,alt_m\n";
  for (int i = 0; i < kFrames + 2; ++i) gnss += fmt::format("{:.3f},49.0,8.4,110.0\n", 99.95 + 0.1 * i);
  WriteText(drive / "gnss.csv", gnss);
  const RunResult result = RunEpiloc(fmt::format("build-db --quiet --drive {} --db {}",
                                                 drive.string(), (root_ / "new.sqlite").string()));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr("two distinct positions"));
  EXPECT_THAT(result.stderr_text, HasSubstr((drive / "gnss.csv").string()));
}

// Issue 18 (unseen inputs): a database whose route polyline collapsed to one point (rows edited
// or written by another tool) gave "route: needs at least two distinct positions" without the
// database's name.
TEST_F(BuildDbErrors, DegenerateRouteInTheDatabaseNamesIt) {
  const fs::path db = root_ / "degenerate.sqlite";
  fs::copy_file(db_, db);
  sqlite3* handle = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &handle), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(handle, "UPDATE route_points SET e_m = 0, n_m = 0, u_m = 0", nullptr,
                         nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(handle);
  const RunResult result =
      RunEpiloc(fmt::format("localize --db {} --drive {} --out {}", db.string(),
                            (root_ / "good").string(), (root_ / "degenerate.csv").string()));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr(db.string() + ": route: needs at least two"));
  EXPECT_FALSE(fs::exists(root_ / "degenerate.csv"));
}

// Issue 18 (unseen inputs): `epiloc info > /dev/full` lost its whole output and exited 0.
TEST_F(BuildDbErrors, StandardOutputThatCannotBeWrittenIsAnError) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  const std::string command =
      fmt::format("{} info --db {} 2>&1 1>/dev/full", EPILOC_BINARY, db_.string());
  FILE* pipe = popen(command.c_str(), "r");
  std::string err;
  std::array<char, 4096> buffer{};
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) err += buffer.data();
  const int status = pclose(pipe);
  EXPECT_EQ(WIFEXITED(status) ? WEXITSTATUS(status) : -1, 1) << err;
  EXPECT_EQ(NumLines(err), 1) << err;
  EXPECT_THAT(err, HasSubstr("epiloc info: error: standard output: write failed"));
}

TEST_F(BuildDbErrors, LatitudeOutOfRange) {
  const fs::path drive = CopyDrive("bad_lat");
  ReplaceLine(drive / "gnss.csv", 3, "100.15,123.0,8.4,110.0");
  ExpectFailure(drive, "gnss.csv:3");
}

TEST_F(BuildDbErrors, DatabaseFromNewerSchema) {
  const fs::path newer = root_ / "newer.sqlite";
  fs::copy_file(db_, newer);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(newer.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version = 999", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  const RunResult result = RunEpiloc(fmt::format("build-db --quiet --drive {} --db {}",
                                                 CopyDrive("other").string(), newer.string()));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr("newer.sqlite"));
  EXPECT_THAT(result.stderr_text, HasSubstr("newer than this epiloc"));
}

TEST_F(BuildDbErrors, LockedDatabase) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(db_.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr), SQLITE_OK);
  const RunResult result = RunEpiloc(fmt::format("build-db --quiet --drive {} --db {}",
                                                 CopyDrive("other").string(), db_.string()));
  sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr("route.sqlite"));
  EXPECT_THAT(result.stderr_text, HasSubstr("locked"));
  EXPECT_EQ(Snapshot(db_), before_);
}

TEST_F(BuildDbErrors, UnknownOptionIsAUsageError) {
  const RunResult result = RunEpiloc(fmt::format("build-db --quiet --drive {} --db {} --sift-foo 3",
                                                 CopyDrive("other").string(), db_.string()));
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_EQ(NumLines(result.stderr_text), 1) << result.stderr_text;
  EXPECT_THAT(result.stderr_text, HasSubstr("--sift-foo"));
  EXPECT_EQ(Snapshot(db_), before_);
}

TEST_F(BuildDbErrors, SecondDriveAndRerunAddNoDuplicates) {
  const fs::path drive = CopyDrive("second");
  const std::string args =
      fmt::format("build-db --quiet --drive {} --db {}", drive.string(), db_.string());
  ASSERT_EQ(RunEpiloc(args).exit_code, 0);
  const std::string after_second = Snapshot(db_);
  EXPECT_NE(after_second, before_);
  EXPECT_THAT(after_second, HasSubstr(fmt::format("{};good,second;", 2 * kFrames)));
  ASSERT_EQ(RunEpiloc(args).exit_code, 0);
  EXPECT_EQ(Snapshot(db_), after_second);
}

}  // namespace
}  // namespace epiloc
