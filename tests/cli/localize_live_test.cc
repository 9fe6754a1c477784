// `epiloc localize` on live input: a drive that grows while it is localized (--follow, rows on
// standard output as frames are done), a video file (--video), and the NMEA output (--nmea-out).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "epiloc/eval/evaluate.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/nmea_writer.h"
#include "epiloc/io/position_readers.h"
#include "epiloc/io/result.h"
#include "localize/localize_test_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string World() { return SharedRoute("epiloc_localize_live_test_v1", SmallStreetOptions()); }

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Runs the epiloc binary with `args`; returns the exit code.
int RunEpiloc(const std::string& args) {
  return std::system(fmt::format("{} {} 2>/dev/null", EPILOC_BINARY, args).c_str()) == 0 ? 0 : 1;
}

TEST(LocalizeLive, FollowAGrowingDriveGivesRowsBeforeTheInputEnds) {
  const std::string world = World();
  const Drive query = LoadDrive(world + "/query");
  TempDir tmp;
  GrowingDrive growing(fs::path(world) / "query", tmp / "growing");
  const fs::path& drive = growing.dir;
  std::ofstream& frames = growing.frames;
  std::ofstream& gnss = growing.gnss;
  size_t next_gnss = 0;
  const auto append = [&](size_t i) {
    // GNSS up to the frame's time, as a receiver delivers it; then the frame row (its image
    // already exists).
    const double t = query.frames[i].timestamp_s;
    for (; next_gnss < query.gnss.samples.size() &&
           query.gnss.samples[next_gnss].timestamp_s <= t + 1e-9;
         ++next_gnss) {
      const PositionSample& s = query.gnss.samples[next_gnss];
      gnss << fmt::format("{:.6f},{:.10f},{:.10f},{:.4f}\n", s.timestamp_s, s.position.lat_deg,
                          s.position.lon_deg, s.position.alt_m)
           << std::flush;
    }
    frames << query.frames[i].frame << "," << fmt::format("{:.6f}", t) << ","
           << query.frames[i].image << "\n"
           << std::flush;
  };

  const std::string command = fmt::format(
      "{} localize --db {}/route.sqlite --drive {} --follow --idle-timeout-s 4 "
      "--out - -q 2>/dev/null",
      EPILOC_BINARY, world, drive.string());
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::mutex mutex;
  std::map<frame_t, double> online_row_at_s;  // frame -> when its online row arrived
  std::string output;
  const auto start = Clock::now();
  std::thread reader([&] {
    char buffer[4096];
    while (std::fgets(buffer, sizeof buffer, pipe)) {
      const std::string line(buffer);
      std::lock_guard<std::mutex> lock(mutex);
      output += line;
      const std::vector<std::string> fields = SplitCsvLine(line);
      if (fields.size() > 7 && fields[7] == "online") {
        online_row_at_s[std::stoll(fields[0])] = SecondsSince(start);
      }
    }
  });

  const size_t half = query.frames.size() / 2;
  for (size_t i = 0; i < half; ++i) {
    append(i);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // Wait for the first half's rows before the second half exists.
  bool first_half_done = false;
  for (int k = 0; k < 2400 && !first_half_done; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::lock_guard<std::mutex> lock(mutex);
    first_half_done = online_row_at_s.count(query.frames[half - 1].frame) > 0;
  }
  const double second_half_written_s = SecondsSince(start);
  for (size_t i = half; i < query.frames.size(); ++i) append(i);
  reader.join();
  EXPECT_EQ(pclose(pipe), 0);
  ASSERT_TRUE(first_half_done) << "no rows for the first half within 120 s:\n" << output;
  for (size_t i = 0; i < half; ++i) {
    ASSERT_EQ(online_row_at_s.count(query.frames[i].frame), 1u) << i;
    EXPECT_LT(online_row_at_s[query.frames[i].frame], second_half_written_s) << i;
  }
  // Every frame has its rows, and standard output is a result CSV.
  WriteText(tmp / "out.csv", output);
  const ResultTable table = ReadResultCsv(tmp / "out.csv");
  int ok = 0;
  for (const ResultRow& row : table.rows) {
    ok += row.method == "online" && row.status == ResultStatus::kOk ? 1 : 0;
  }
  EXPECT_EQ(online_row_at_s.size(), query.frames.size());
  EXPECT_GE(ok, static_cast<int>(query.frames.size()) * 9 / 10);
}

TEST(LocalizeLive, VideoFileWithCalibrationAndGnss) {
  const std::string world = World();
  const Drive query = LoadDrive(world + "/query");
  TempDir tmp;
  const std::string video = tmp / "query.avi";
  {
    const double fps = (query.frames.size() - 1) /
                       (query.frames.back().timestamp_s - query.frames.front().timestamp_s);
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps,
                           cv::Size(query.camera.width, query.camera.height));
    ASSERT_TRUE(writer.isOpened());
    for (const FrameRecord& f : query.frames) writer.write(cv::imread(query.ImagePath(f)));
  }
  ASSERT_EQ(RunEpiloc(fmt::format(
                "localize --db {}/route.sqlite --video {} --calibration "
                "{}/query/drive.json --gnss {}/query/gnss.csv --video-start-s {:.6f} "
                "--out {} -q",
                world, video, world, world, query.frames.front().timestamp_s, tmp / "video.csv")),
            0);
  const ResultTable result = ReadResultCsv(tmp / "video.csv");
  EvaluateOptions evaluate;
  evaluate.association = Association::kTime;
  const Evaluation evaluation =
      Evaluate(result, *query.ground_truth, RouteFromDatabase(world + "/route.sqlite"), evaluate);
  const MethodEvaluation* online = evaluation.Find("online");
  ASSERT_NE(online, nullptr);
  std::cout << "video: " << online->evaluated() << " of " << query.frames.size()
            << " frames, along-track mean " << online->along_track.mean_abs << " m\n";
  EXPECT_GE(online->evaluated(), static_cast<int64_t>(query.frames.size()) * 9 / 10);
  EXPECT_LE(online->along_track.mean_abs, 0.1);
}

TEST(LocalizeLive, NmeaOutputHasValidChecksumsAndTheCsvPositions) {
  const std::string world = World();
  TempDir tmp;
  ASSERT_EQ(RunEpiloc(fmt::format("localize --db {0}/route.sqlite --drive {0}/query --out {1} "
                                  "--nmea-out {2} -q",
                                  world, tmp / "r.csv", tmp / "r.nmea")),
            0);
  std::ifstream in(tmp / "r.nmea");
  std::string line;
  int sentences = 0;
  while (std::getline(in, line)) {
    ASSERT_FALSE(line.empty());
    if (line.back() == '\r') line.pop_back();
    ASSERT_EQ(line[0], '$') << line;
    const size_t star = line.rfind('*');
    ASSERT_NE(star, std::string::npos) << line;
    EXPECT_EQ(line.substr(star + 1), NmeaChecksum(line.substr(1, star - 1))) << line;
    if (line.compare(3, 3, "GGA") == 0) {
      EXPECT_NE(line.find(",6,"), std::string::npos) << "fix quality 6 (estimated): " << line;
    }
    ++sentences;
  }
  const PositionTrack nmea = ReadNmea(tmp / "r.nmea");
  // The position each frame's NMEA epoch should carry: pnp where it was refined, else online.
  std::map<int64_t, Geodetic> expected;  // by time in hundredths of a second
  for (const ResultRow& row : ReadResultCsv(tmp / "r.csv").rows) {
    if (row.status != ResultStatus::kOk || !row.has_position) continue;
    const int64_t key = std::llround(row.timestamp_s * 100.0);
    if (row.method == "pnp" || expected.count(key) == 0) expected[key] = row.position;
  }
  ASSERT_EQ(nmea.samples.size(), expected.size());
  EXPECT_EQ(sentences, 2 * static_cast<int>(expected.size()));
  for (const PositionSample& sample : nmea.samples) {
    const int64_t key = std::llround(sample.timestamp_s * 100.0);
    ASSERT_EQ(expected.count(key), 1u) << FormatDouble(sample.timestamp_s);
    const Eigen::Vector3d d = EnuFrame(expected[key]).ToEnu(sample.position);
    EXPECT_LT(d.norm(), 0.01) << FormatDouble(sample.timestamp_s);
  }
}

}  // namespace
}  // namespace epiloc
