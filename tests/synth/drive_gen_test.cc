#include "epiloc/synth/drive_gen.h"

#include <unistd.h>
#include <cmath>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "epiloc/core/error.h"
#include "epiloc/core/hash.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// A small, fast data set: 40 m, few frames, coarse LiDAR.
SynthOptions TinyOptions(uint64_t seed) {
  SynthOptions o;
  o.length_m = 40;
  o.seed = seed;
  o.world.margin_after_m = 40;
  o.survey.frame_rate_hz = 1.0;
  o.query.frame_rate_hz = 1.0;
  o.query.start_offset_m = 5;
  o.query.end_offset_m = 5;
  o.lidar_options.scan_spacing_m = 20;
  o.lidar_options.azimuth_step_deg = 1.0;
  o.lidar_scan_files = true;
  return o;
}

World SmallWorld() {
  WorldOptions o;
  o.length_m = 60;
  o.margin_after_m = 20;
  o.seed = 2;
  return BuildWorld(o);
}

std::string TempDir(const std::string& name) {
  // Per process: the same test may run from another checkout at the same time.
  const fs::path dir =
      fs::temp_directory_path() / ("epiloc_synth_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir.string();
}

TEST(Trajectory, GroundTruthMatchesTheRenderedPoses) {
  const World world = SmallWorld();
  const EnuFrame frame(world.origin());
  for (const DriveOptions& drive : {DriveOptions::Survey(), DriveOptions::Query()}) {
    const DrivePath path(world, drive, world.options.length_m, 3);
    const std::vector<double> times = path.FrameTimes();
    const PositionTrack truth = GroundTruthTrack(path, frame, times);
    ASSERT_EQ(truth.samples.size(), times.size());
    double max_position = 0, max_angle = 0;
    for (size_t i = 0; i < times.size(); ++i) {
      const PositionSample& sample = truth.samples[i];
      EXPECT_EQ(sample.frame, static_cast<frame_t>(i));
      const Rigid3d world_from_cam = path.CamFromWorld(times[i]).Inverse();
      const Eigen::Vector3d centre = world_from_cam.translation;
      max_position = std::max(max_position, (frame.ToEnu(sample.position) - centre).norm());
      // The local ENU axes at the sample, measured in the world frame by stepping 1 m along them.
      const EnuFrame local(sample.position);
      Eigen::Matrix3d world_from_local;
      for (int a = 0; a < 3; ++a) {
        world_from_local.col(a) =
            frame.ToEnu(local.ToGeodetic(Eigen::Vector3d::Unit(a))) - frame.ToEnu(sample.position);
      }
      const Eigen::Quaterniond expected(world_from_local.transpose() *
                                        world_from_cam.rotation.toRotationMatrix());
      max_angle = std::max(max_angle, RotationDifferenceDeg(*sample.enu_from_cam, expected));
    }
    std::printf("%s: %zu frames, position error %.2e m, orientation error %.2e deg\n",
                drive.name.c_str(), times.size(), max_position, max_angle);
    EXPECT_LT(max_position, 1e-3);
    EXPECT_LT(max_angle, 1e-4);
  }
}

TEST(Trajectory, SpeedProfileStopsAndSpeedsUp) {
  const World world = SmallWorld();
  DriveOptions drive = DriveOptions::Query();
  // Long enough to reach 10 m/s (the centreline continues beyond the small world).
  const DrivePath path(world, drive, 300.0, 3);
  EXPECT_NEAR(path.start_s_m(), drive.start_offset_m, 1e-9);
  EXPECT_NEAR(path.end_s_m(), 300.0 - drive.end_offset_m, 1e-9);
  const double s_stop = drive.start_offset_m + 0.3 * (path.end_s_m() - path.start_s_m());
  const double t_stop = path.TimeAtS(s_stop);
  EXPECT_NEAR(path.SAt(t_stop + 1.0), s_stop, 0.05);  // still standing 1 s later
  const double fast =
      path.TimeAtS(drive.start_offset_m + 0.7 * (path.end_s_m() - path.start_s_m()));
  EXPECT_NEAR(path.SAt(fast + 0.5) - path.SAt(fast - 0.5), 10.0, 0.5);
  for (double t = path.start_time_s(); t < path.end_time_s(); t += 0.1) {
    EXPECT_LE(path.SAt(t), path.SAt(t + 0.1) + 1e-12);
  }
}

TEST(Trajectory, GnssErrorsFollowTheModel) {
  const World world = SmallWorld();
  const EnuFrame frame(world.origin());
  DriveOptions drive = DriveOptions::Query();
  const DrivePath path(world, drive, world.options.length_m, 3);
  GnssOptions exact;
  exact.sigma_m = 0;
  for (const PositionSample& s : SimulateGnss(path, frame, exact, 1).samples) {
    EXPECT_LT(
        (frame.ToEnu(s.position) - path.CamFromWorld(s.timestamp_s).Inverse().translation).norm(),
        1e-6);
  }
  GnssOptions gnss;
  gnss.rate_hz = 20;
  const PositionTrack a = SimulateGnss(path, frame, gnss, 1);
  const PositionTrack b = SimulateGnss(path, frame, gnss, 1);
  const PositionTrack c = SimulateGnss(path, frame, gnss, 2);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  Eigen::Vector3d sum_sq = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < a.samples.size(); ++i) {
    EXPECT_EQ(a.samples[i].position.lat_deg, b.samples[i].position.lat_deg);
    EXPECT_NE(a.samples[i].position.lat_deg, c.samples[i].position.lat_deg);
    const Eigen::Vector3d e = frame.ToEnu(a.samples[i].position) -
                              path.CamFromWorld(a.samples[i].timestamp_s).Inverse().translation;
    sum_sq += e.cwiseProduct(e);
    if (i > 0) {
      // Consecutive errors are strongly correlated (the bias), but not equal (white noise).
      const Eigen::Vector3d prev =
          frame.ToEnu(a.samples[i - 1].position) -
          path.CamFromWorld(a.samples[i - 1].timestamp_s).Inverse().translation;
      EXPECT_LT((e - prev).head<2>().norm(), 6 * std::sqrt(2 * 0.19) * gnss.sigma_m);
      EXPECT_GT((e - prev).norm(), 1e-6);
    }
  }
  const Eigen::Vector3d rms = (sum_sq / a.samples.size()).cwiseSqrt();
  std::printf("GNSS rms error over %zu samples: E %.2f N %.2f U %.2f m\n", a.samples.size(),
              rms.x(), rms.y(), rms.z());
  EXPECT_LT(rms.head<2>().maxCoeff(), 5 * gnss.sigma_m);
}

TEST(GenerateSynthetic, WritesLoadableDrivesAndIsDeterministic) {
  const std::string a = TempDir("a"), b = TempDir("b"), c = TempDir("c");
  const SynthSummary summary = GenerateSynthetic(TinyOptions(5), a);
  GenerateSynthetic(TinyOptions(5), b);
  int64_t last_done = 0, last_total = 0;
  GenerateSynthetic(TinyOptions(6), c, [&](int64_t done, int64_t total) {
    EXPECT_GT(done, last_done);
    last_done = done;
    last_total = total;
  });
  EXPECT_EQ(last_done, last_total);
  EXPECT_GT(summary.num_survey_frames, 3);
  EXPECT_GT(summary.num_query_frames, 3);
  EXPECT_GT(summary.num_lidar_points, 10000);
  for (const char* file : {"world.json", "top_view.png", "lidar/map.ply", "lidar/scans.csv",
                           "survey/images/000002.png", "query/images/000002.png", "survey/gnss.csv",
                           "query/gnss.csv", "query/ground_truth.csv"}) {
    ASSERT_TRUE(fs::exists(fs::path(a) / file)) << file;
    EXPECT_EQ(HashFile((fs::path(a) / file).string()), HashFile((fs::path(b) / file).string()))
        << file;
  }
  for (const char* file : {"survey/images/000002.png", "query/gnss.csv", "lidar/map.ply"}) {
    EXPECT_NE(HashFile((fs::path(a) / file).string()), HashFile((fs::path(c) / file).string()))
        << file;
  }

  const SynthOptions options = TinyOptions(5);
  const Drive survey = LoadDrive((fs::path(a) / "survey").string());
  const Drive query = LoadDrive((fs::path(a) / "query").string());
  EXPECT_EQ(survey.camera, options.survey.camera);
  EXPECT_EQ(query.camera, options.query.camera);
  EXPECT_TRUE(query.camera.HasDistortion());
  EXPECT_EQ(static_cast<int>(survey.frames.size()), summary.num_survey_frames);
  EXPECT_EQ(static_cast<int>(query.frames.size()), summary.num_query_frames);
  ASSERT_TRUE(query.ground_truth.has_value());
  EXPECT_EQ(query.ground_truth->samples.size(), query.frames.size());
  EXPECT_FALSE(query.gnss.samples.empty());
  EXPECT_EQ(survey.lidar.size(), static_cast<size_t>(summary.num_lidar_scans));
  EXPECT_TRUE(fs::exists(fs::path(a) / "survey" / survey.lidar[0].path));
  // The stored ground truth is the pose the frames were rendered with.
  const World world = BuildWorld(options.ResolvedWorldOptions());
  const DrivePath path(world, options.query, options.length_m, MixSeed(options.seed, 101));
  const EnuFrame frame(world.origin());
  for (const PositionSample& s : query.ground_truth->samples) {
    EXPECT_LT(
        (frame.ToEnu(s.position) - path.CamFromWorld(s.timestamp_s).Inverse().translation).norm(),
        1e-3);
  }
  for (const std::string& dir : {a, b, c}) fs::remove_all(dir);
}

TEST(GenerateSynthetic, QueryOnlyWritesTheSameQueryAndNoSurveyFrames) {
  const std::string full = TempDir("full"), query_only = TempDir("query_only");
  SynthOptions options = TinyOptions(7);
  options.lidar = false;
  // With moving cars: the query's list is written, the survey's (no survey drive) is not.
  options.appearance.moving.traffic = 2;
  const SynthSummary a = GenerateSynthetic(options, full);
  options.survey_frames = false;
  const SynthSummary b = GenerateSynthetic(options, query_only);
  EXPECT_GT(a.num_survey_frames, 3);
  EXPECT_EQ(b.num_survey_frames, 0);
  ASSERT_EQ(a.num_query_frames, b.num_query_frames);
  EXPECT_FALSE(fs::exists(fs::path(query_only) / "survey"));
  for (const std::string file :
       {"query/drive.json", "query/frames.csv", "query/gnss.csv", "query/ground_truth.csv",
        "query/images/000000.png", "query/images/000003.png", "world.json",
        "query/moving_objects.csv"}) {
    ASSERT_TRUE(fs::exists(fs::path(query_only) / file)) << file;
    EXPECT_EQ(HashFile((fs::path(full) / file).string()),
              HashFile((fs::path(query_only) / file).string()))
        << file;
  }
  for (const std::string& dir : {full, query_only}) fs::remove_all(dir);
}

// Issue 14's query variants on disk: grey JPEG frames, and a still stand repeating its frame.
TEST(GenerateSynthetic, GreyJpegFramesAndStillStops) {
  SynthOptions options = TinyOptions(5);
  options.lidar = false;
  options.query.grey = true;
  options.query.jpeg_quality = 80;
  options.query.frame_rate_hz = 2.0;
  options.query.stops = {{0.0, 3.0, 8.0}};  // 3 s, 8 m after the start
  options.query.still_when_stopped = true;
  const std::string dir = TempDir("grey_jpeg");
  GenerateSynthetic(options, dir);
  const Drive survey = LoadDrive((fs::path(dir) / "survey").string());
  const Drive query = LoadDrive((fs::path(dir) / "query").string());
  EXPECT_TRUE(survey.colour);
  EXPECT_FALSE(query.colour);
  const FrameReader reader(query);
  std::vector<std::string> hashes;
  for (size_t i = 0; i < query.frames.size(); ++i) {
    const std::string path = (fs::path(query.dir) / query.frames[i].image).string();
    ASSERT_EQ(fs::path(path).extension(), ".jpg");
    std::ifstream file(path, std::ios::binary);
    unsigned char magic[3] = {0, 0, 0};
    file.read(reinterpret_cast<char*>(magic), 3);
    EXPECT_TRUE(magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF) << path;
    const cv::Mat stored = cv::imread(path, cv::IMREAD_UNCHANGED);
    EXPECT_EQ(stored.channels(), 1) << path;
    EXPECT_EQ(stored.cols, query.camera.width);
    EXPECT_EQ(reader.ReadGrey(i).size(), stored.size());
    hashes.push_back(HashFile(path));
  }
  EXPECT_EQ(
      cv::imread((fs::path(survey.dir) / survey.frames[0].image).string(), cv::IMREAD_UNCHANGED)
          .channels(),
      3);
  // Over the stand the ground truth and the files repeat; elsewhere they change.
  int repeated = 0, changed = 0;
  const std::vector<PositionSample>& truth = query.ground_truth->samples;
  for (size_t i = 1; i < truth.size(); ++i) {
    const bool same = truth[i].position.lat_deg == truth[i - 1].position.lat_deg &&
                      truth[i].position.lon_deg == truth[i - 1].position.lon_deg &&
                      truth[i].enu_from_cam->coeffs() == truth[i - 1].enu_from_cam->coeffs();
    EXPECT_EQ(same, hashes[i] == hashes[i - 1]) << "frame " << i;
    (same ? repeated : changed) += 1;
  }
  EXPECT_GE(repeated, 5);  // 3 s at 2 Hz
  EXPECT_GE(changed, 5);
  fs::remove_all(dir);
}

TEST(GenerateSynthetic, OptionsAreChecked) {
  SynthOptions o;
  o.length_m = 5;
  EXPECT_THROW(o.Check(), Error);
  o = SynthOptions();
  o.query.frame_rate_hz = 0;
  EXPECT_THROW(o.Check(), Error);
  // Issue 18 (unseen inputs): --length-m 1e9 ran without end, --query-speed-mps 1e-9 took 6.8 GB
  // within a minute, --query-rate-hz 1e6 likewise; --gps-noise 1e308 was taken.
  const auto message_of = [](const SynthOptions& options) {
    try {
      options.Check();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  o = SynthOptions();
  o.length_m = 1e9;
  EXPECT_NE(message_of(o).find("at most 5000 m"), std::string::npos) << message_of(o);
  o = SynthOptions();
  o.query.speed_mps = 1e-9;
  EXPECT_NE(message_of(o).find("at most 200000"), std::string::npos) << message_of(o);
  o = SynthOptions();
  o.query.frame_rate_hz = 1e6;
  EXPECT_NE(message_of(o).find("at most 200000"), std::string::npos) << message_of(o);
  o = SynthOptions();
  o.query.gnss.sigma_m = 1e308;
  EXPECT_NE(message_of(o).find("sigma_m"), std::string::npos) << message_of(o);
  o = SynthOptions();
  o.length_m = 5000;
  o.Check();  // the longest street still passes with the default drives
  o = SynthOptions();
  o.query.camera.fx = -1;
  EXPECT_THROW(GenerateSynthetic(o, TempDir("bad")), Error);
}

}  // namespace
}  // namespace epiloc
