// Monocular VO end to end: on a small synthetic drive (exact ground truth) and on the shared
// KITTI drive (skipped when ../shared/data is absent). The trajectory is compared with the ground
// truth after the least-squares Sim(3) alignment (georef/similarity.h), the usual absolute
// trajectory error of monocular odometry; drift is that error in % of the distance driven.
#include "epiloc/vo/visual_odometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/geo/geodetic.h"
#include "epiloc/georef/similarity.h"
#include "epiloc/io/kitti.h"
#include "epiloc/io/pose_files.h"
#include "epiloc/synth/drive_gen.h"
#include "synth_world_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// A 90 m synthetic street; its query drive (70 m of dashcam at 15 Hz: noise, motion blur,
// wobble, lens distortion, a 2 s stop and a faster part) is the VO input. No LiDAR and a sparse
// survey keep the generation short. Generated once per machine into the temporary directory
// (private directory, then renamed, so concurrent test processes never see a partial world).
std::string SharedVoWorld() {
  SynthOptions options;
  options.length_m = 90.0;
  options.seed = 5;
  options.lidar = false;
  options.survey.frame_rate_hz = 1.0;
  return SharedWorld("epiloc_vo_test_world_v1", options);
}

// The VO trajectory against the drive's ground truth after Sim(3) alignment.
struct Alignment {
  int64_t poses = 0;        // VO poses with a ground-truth position
  double distance_m = 0.0;  // ground-truth path length over them
  double rms_m = 0.0;       // position error after alignment
  double max_m = 0.0;
  double scale = 0.0;  // metres per VO unit
  double max_percent() const { return 100.0 * max_m / distance_m; }
  double rms_percent() const { return 100.0 * rms_m / distance_m; }
};

Alignment AlignToTruth(const VoResult& result, const Drive& drive) {
  Alignment a;
  EXPECT_TRUE(drive.ground_truth.has_value());
  if (!drive.ground_truth || drive.ground_truth->samples.empty()) return a;
  const EnuFrame enu(drive.ground_truth->samples.front().position);
  std::vector<Eigen::Vector3d> vo, truth;
  for (const VoFramePose& pose : result.poses) {
    const auto sample = drive.ground_truth->Interpolate(pose.timestamp_s, drive.max_gap_s);
    if (!sample) continue;
    vo.push_back(pose.world_from_cam.translation);
    truth.push_back(enu.ToEnu(sample->position));
    if (truth.size() > 1) a.distance_m += (truth.back() - truth[truth.size() - 2]).norm();
  }
  a.poses = static_cast<int64_t>(vo.size());
  const auto sim = FitSim3(vo, truth);
  EXPECT_TRUE(sim.has_value()) << "VO trajectory degenerate (" << vo.size() << " poses)";
  if (!sim) return a;
  const FitResiduals r = Residuals(*sim, vo, truth);
  a.rms_m = r.rms_m;
  a.max_m = r.max_m;
  a.scale = sim->scale;
  return a;
}

void Print(const char* what, const VoResult& result, const Alignment& a) {
  const VoSummary& s = result.summary;
  std::printf(
      "%s: %lld/%lld frames posed, %lld keyframes, %zu segment(s), %.1f frames/s (global BA "
      "%.2f s); aligned over %lld poses, %.1f m: rms %.3f m (%.2f %%), max %.3f m (%.2f %%)\n",
      what, static_cast<long long>(s.posed), static_cast<long long>(s.frames),
      static_cast<long long>(s.keyframes), result.segments.size(), s.frames_per_s(),
      s.global_ba_seconds, static_cast<long long>(a.poses), a.distance_m, a.rms_m, a.rms_percent(),
      a.max_m, a.max_percent());
}

TEST(VisualOdometry, OptionsAndFramesAreChecked) {
  VoOptions options;
  EXPECT_NO_THROW(options.Check());
  options.min_inliers = 3;
  ExpectError([&] { options.Check(); }, {"min_inliers"});
  options = VoOptions();
  options.ba_window = 1;
  ExpectError([&] { options.Check(); }, {"ba_window"});
  Camera camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 50.0;
  camera.cx = 31.5;
  camera.cy = 23.5;
  VisualOdometry odometry(camera, VoOptions());
  ExpectError([&] { odometry.ProcessFrame(0, 0.0, cv::Mat(40, 64, CV_8UC1, cv::Scalar(0))); },
              {"frame 0 is 64x40, the camera 64x48"});
  ExpectError([&] { odometry.ProcessFrame(1, 0.0, cv::Mat(48, 64, CV_16UC1, cv::Scalar(0))); },
              {"frame 1 is not an 8-bit grey or BGR image"});
  EXPECT_EQ(odometry.ProcessFrame(2, 1.0, cv::Mat(48, 64, CV_8UC1, cv::Scalar(0))),
            VoFrameStatus::kInitializing);
  ExpectError([&] { odometry.ProcessFrame(3, 0.5, cv::Mat(48, 64, CV_8UC1, cv::Scalar(0))); },
              {"before the previous frame"});
  EXPECT_TRUE(odometry.Result().poses.empty());
}

// The synthetic dashcam drive: one segment, (nearly) every frame posed, and the shape after
// Sim(3) alignment within 0.3 % of the distance at every pose. Measured: 259 of 259 frames posed,
// rms 0.022 m (0.03 %), max 0.066 m (0.09 %) over 69 m; ~7-10 s of VO plus ~11 s to generate the
// world the first time.
TEST(VisualOdometry, SyntheticDriveKeepsItsShape) {
  const Drive drive = LoadDrive(SharedVoWorld() + "/query");
  ASSERT_TRUE(drive.ground_truth.has_value());
  const VoResult result = RunVisualOdometry(drive, VoOptions());
  const Alignment a = AlignToTruth(result, drive);
  Print("synthetic", result, a);
  EXPECT_EQ(result.summary.frames, static_cast<int64_t>(drive.frames.size()));
  EXPECT_EQ(result.summary.lost, 0);
  EXPECT_EQ(result.segments.size(), 1u);
  EXPECT_GE(result.summary.posed, result.summary.frames * 9 / 10);
  EXPECT_GE(result.summary.keyframes, 5);
  EXPECT_GT(a.distance_m, 50.0);
  EXPECT_LT(a.max_percent(), 0.3);
  EXPECT_LT(a.rms_percent(), 0.15);
  // Poses come in time order, keyframes flagged.
  for (size_t i = 1; i < result.poses.size(); ++i) {
    EXPECT_GT(result.poses[i].timestamp_s, result.poses[i - 1].timestamp_s);
  }
  // The trajectory file round-trips (TUM, one pose per posed frame).
  TempDir dir;
  WriteVoTrajectory(result, dir / "vo.tum", drive.name);
  const std::vector<StampedPose> back = ReadTumPoses(dir / "vo.tum");
  ASSERT_EQ(back.size(), result.poses.size());
  EXPECT_LT(
      (back.back().world_from_cam.translation - result.poses.back().world_from_cam.translation)
          .norm(),
      1e-9);
}

// The shared KITTI drive, camera 1 (1242x375, 154 frames, 69 m): drift after Sim(3) alignment,
// the target <= 2 % of the distance at every pose. Measured with the global BA and 1.5 px
// inlier threshold against the OXTS positions fused with the unit's velocity (import-kitti's
// default): rms 0.561 m (0.82 %), max 1.256 m (1.83 %); against the raw positions rms 0.639 m
// (0.92 %), max 1.146 m (1.66 %). 11-20 frames/s on 2 busy cores (global BA 0.8 s).
TEST(VisualOdometry, KittiCamera1Drift) {
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  TempDir dir;
  KittiImportOptions import;
  import.raw_drive_dir = raw.string();
  import.camera = 1;
  import.out_dir = dir / "cam1";
  ImportKitti(import);
  const Drive drive = LoadDrive(dir / "cam1");
  const VoResult result = RunVisualOdometry(drive, VoOptions());
  const Alignment a = AlignToTruth(result, drive);
  Print("kitti cam1", result, a);
  EXPECT_EQ(result.summary.lost, 0);
  EXPECT_GE(result.summary.posed, result.summary.frames * 9 / 10);
  EXPECT_GT(a.distance_m, 50.0);
  EXPECT_LE(a.max_percent(), 2.0);
  EXPECT_LE(a.rms_percent(), 1.1);
}

}  // namespace
}  // namespace epiloc
