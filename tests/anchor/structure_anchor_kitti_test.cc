// Anchoring from structure on the shared KITTI drive (skipped without ../shared/data): the
// development scenario of issue 17. Map from camera 0's LiDAR scans (every 5th scan in the shared
// copy, intensity only, no colour, no photographs); camera 1 with 3 m GNSS noise and a heading
// error of up to 5 degrees; its own monocular VO structure registered to the map; anchors against
// the OXTS camera pose.
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "epiloc/anchor/build_map.h"
#include "epiloc/anchor/lidar_track.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/io/kitti.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? NAN : v[v.size() / 2];
}

TEST(StructureAnchorKitti, AnchorsCameraOneFromItsOwnStructure) {
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  TempDir dir;
  KittiImportOptions cam0;
  cam0.raw_drive_dir = raw.string();
  cam0.camera = 0;
  cam0.out_dir = dir / "cam0";
  ImportKitti(cam0);
  KittiImportOptions cam1 = cam0;
  cam1.camera = 1;
  cam1.gps_noise_sigma_m = 3.0;
  cam1.seed = 1;
  cam1.stop = 100;  // the first 45 m (of 69 m) keep the VO, and the test, short
  cam1.out_dir = dir / "cam1";
  ImportKitti(cam1);
  const std::string map = dir / "map.ply";
  BuildMap(cam0.out_dir, map, std::nullopt, "", BuildMapOptions());
  const Drive drive = LoadDrive(cam1.out_dir);
  const VoStructure vo = VoStructure::FromResult(RunVisualOdometry(drive, VoOptions()));

  AnchorInputs inputs;
  inputs.cloud_path = map;
  inputs.map_origin = ReadMapSidecar(SidecarPath(map)).enu_origin;
  inputs.drive_dir = cam1.out_dir;
  inputs.every = 15;  // 7 anchors keep the test short; README: the whole drive, every 10th
  StructureAnchorOptions options;
  options.heading_error_deg = 5.0;
  // Errors of every anchor with a pose, ok or rejected (the along-track profile rejects them
  // all as weak along the road, README).
  struct Figures {
    std::vector<double> horizontal, rotation;
    double ok_max_horizontal = 0.0;  // of the anchors called ok
    int ok = 0;
    double seconds = 0.0;
    size_t anchors = 0;
  };
  const auto run_on = [&](const AnchorInputs& in, const Drive& truth_drive,
                          const VoStructure& structure, const StructureAnchorOptions& o,
                          const char* label) {
    const EnuFrame enu(in.map_origin);
    const AnchorDriveResult result = AnchorDriveByStructure(in, structure, o);
    Figures f;
    f.anchors = result.frames.size();
    for (const AnchorResult& a : result.frames) {
      f.seconds += a.seconds / static_cast<double>(result.frames.size());
      f.ok += a.status == AnchorStatus::kOk ? 1 : 0;
      if (!a.has_pose) {
        std::printf("%s frame %3lld: %s %s\n", label, static_cast<long long>(a.frame),
                    AnchorStatusName(a.status).c_str(), a.message.c_str());
        continue;
      }
      const auto truth = TrueMapFromCam(truth_drive, a.timestamp_s, enu);
      EXPECT_TRUE(truth.has_value());
      if (!truth) continue;
      f.horizontal.push_back((a.map_from_cam.translation - truth->translation).head<2>().norm());
      f.rotation.push_back(RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation));
      if (a.status == AnchorStatus::kOk) {
        f.ok_max_horizontal = std::max(f.ok_max_horizontal, f.horizontal.back());
      }
      std::printf(
          "%s frame %3lld: %s %.3f m, %.2f deg, share %.2f, residual %.3f m, scale %.4f, drift "
          "%.2f %% per 10 m, along sigma %.3f m\n",
          label, static_cast<long long>(a.frame), AnchorStatusName(a.status).c_str(),
          f.horizontal.back(), f.rotation.back(), a.inlier_share, a.residual_m, a.scale_m_per_unit,
          1000.0 * a.scale_drift_per_m, a.along_sigma_m);
    }
    std::printf(
        "KITTI structure anchors (%s): %d of %zu ok, %zu posed: horizontal median %.3f max %.3f "
        "m, rotation median %.2f max %.2f deg, %.2f s per anchor\n",
        label, f.ok, f.anchors, f.horizontal.size(), Median(f.horizontal),
        f.horizontal.empty() ? NAN : *std::max_element(f.horizontal.begin(), f.horizontal.end()),
        Median(f.rotation),
        f.rotation.empty() ? NAN : *std::max_element(f.rotation.begin(), f.rotation.end()),
        f.seconds);
    return f;
  };
  const auto run = [&](const StructureAnchorOptions& o, const char* label) {
    return run_on(inputs, drive, vo, o, label);
  };
  const Figures with_drift = run(options, "drift across anchors");
  StructureAnchorOptions no_drift_options = options;
  no_drift_options.scale_drift = ScaleDriftModel::kNone;
  const Figures no_drift = run(no_drift_options, "no drift model");
  // Targets (issue 17): >= 90 % ok, median <= 0.2 m, max <= 0.5 m, rotation <= 0.5 deg, <= 2 s.
  // Reached (frames 0-99, every 15th), over the 7 posed anchors, with the drift model: median
  // 0.60 m, max 0.79 m, rotation median 1.8 deg, max 2.4 deg; without it 0.82 / 0.90 m and
  // 2.2 / 3.5 deg (this VO's scale falls by 0.2-0.4 % per metre, as the anchors estimate it). None
  // of the accuracy targets is met, partly because this drive's OXTS track is 4 % short of its
  // LiDAR (README); all anchors are rejected as weak along the road. The figures asserted are those
  // reached (with a margin), so that a regression fails: the structure is registered metres better
  // than the GNSS prior (4-7 m off here).
  ASSERT_GE(with_drift.horizontal.size() * 4, with_drift.anchors * 3);
  EXPECT_LE(Median(with_drift.horizontal), 0.9);
  EXPECT_LE(*std::max_element(with_drift.horizontal.begin(), with_drift.horizontal.end()), 1.5);
  EXPECT_LE(Median(with_drift.rotation), 2.4);
  // The drift model places the camera better than one similarity per window.
  EXPECT_LT(Median(with_drift.horizontal), Median(no_drift.horizontal));
  EXPECT_LT(Median(with_drift.rotation), Median(no_drift.rotation));

  // Issue 17's protocol (the whole drive, every 10th frame) with the map and the truth on the
  // track the LiDAR agrees with (lidar_track.h): the OXTS track steps 3.7 % short of the scans and
  // travels 0.4 deg flatter than they do, so its map and its camera poses disagree with each other
  // by about as much as the targets allow.
  const Drive cam0_drive = LoadDrive(cam0.out_dir);
  const EnuFrame track_frame(cam0_drive.lidar.front().sensor_position);
  const LidarTrack track = EstimateLidarTrack(cam0_drive, track_frame, LidarTrackOptions());
  KittiImportOptions cam1_all = cam1;
  cam1_all.stop = -1;
  cam1_all.out_dir = dir / "cam1_all";
  const Drive whole = ImportKitti(cam1_all);
  WriteDrive(CorrectDriveTrack(cam0_drive, track_frame, track), dir / "cam0_lidar");
  WriteDrive(CorrectDriveTrack(whole, track_frame, track), dir / "cam1_lidar");
  const std::string lidar_map = dir / "map_lidar.ply";
  BuildMap(dir / "cam0_lidar", lidar_map, std::nullopt, "", BuildMapOptions());
  AnchorInputs lidar_inputs = inputs;
  lidar_inputs.cloud_path = lidar_map;
  lidar_inputs.map_origin = ReadMapSidecar(SidecarPath(lidar_map)).enu_origin;
  lidar_inputs.drive_dir = dir / "cam1_lidar";
  lidar_inputs.every = 10;
  const Drive lidar_drive = LoadDrive(dir / "cam1_lidar");
  const VoStructure whole_vo = VoStructure::FromResult(RunVisualOdometry(lidar_drive, VoOptions()));
  const Figures lidar =
      run_on(lidar_inputs, lidar_drive, whole_vo, options, "LiDAR-consistent track");
  // Reached (2026-11-28, fifth session): 12 of 16 ok (the drive's two ends and two weak along
  // the road rejected), horizontal median 0.123 m, max 0.405 m (frame 0, at the drive's start);
  // with the drift from the neighbours' scales only 13 of 16 ok, 0.115 / 0.238 m, 0.20 / 0.43 deg;
  // rotation median 0.19 deg, max 0.43 deg; 0.6-1.6 s per anchor (2 threads, the machine
  // otherwise busy or not); with the drift kept only where it fits the map better (sixth
  // session) 14 of 16 ok, 0.125 / 0.238 m, 0.17 / 0.43 deg; with the drift pass in two rounds
  // (2026-12-05) 14 of 16 ok, 0.124 / 0.220 m, 0.21 / 0.43 deg; with the ok claim at the
  // profile's resolution (max_along_sigma_m 0.15: 0.3 m along at 2 sigma, 2026-12-06) 16 of 16;
  // with the consensus placement 0.118 / 0.224 m; with the structure registered at the rotation
  // consensus of 80 m (placement_rotation_radius_m, the same day) 0.079 / 0.205 m, 0.21 / 0.43
  // deg. With the truth at the frames' trigger times (import-kitti's default since 2026-12-06,
  // README "The truth's timing"; before, at the OXTS records 13-21 ms later): 16 of 16 ok,
  // 0.112 / 0.216 m, 0.19 / 0.49 deg. The targets.
  ASSERT_GE(lidar.horizontal.size() * 4, lidar.anchors * 3);
  EXPECT_GE(lidar.ok * 8, static_cast<int>(lidar.anchors) * 7);
  EXPECT_LE(Median(lidar.horizontal), 0.2);
  EXPECT_LE(*std::max_element(lidar.horizontal.begin(), lidar.horizontal.end()), 0.5);
  EXPECT_LE(Median(lidar.rotation), 0.5);

  // Another camera of the same drive: camera 0 (0.54 m to the left, its own images and VO; the
  // GNSS drawn with another seed) on the same map and the LiDAR's path. Its VO's scale stays flat
  // over the first 15 m and then falls 3-4 % per 10 m; the drift the neighbours' scales give,
  // extrapolated to the drive's start, put frames 0-30 0.5-1.7 m behind along the road (all
  // rejected by the neighbours' check; median 0.256 m). With the drift kept only where it fits
  // the map better, and none where the line asks for more than a usable VO drifts
  // (structure_passes.cc), measured 2026-11-28 (sixth session): 6 of 16 ok, every ok anchor
  // within 0.24 m, median 0.173 m, max 0.376 m, rotation max 0.47 deg. With the drift pass in two
  // rounds, the second's drift from the first round's scales (2026-12-05): 11 of 16 ok, every ok
  // anchor within 0.13 m, median 0.106 m, max 0.344 m (frame 0, rejected), rotation max 0.57 deg;
  // over four heading seeds through the CLI 9-11 ok, within 0.133 m, median 0.099-0.100 m, max
  // 0.35-0.40 m. With the ok claim at the profile's resolution (0.3 m along, 2026-12-06): 15 of
  // 16 ok, every ok anchor within 0.30 m (frame 20, 0.28 m along); with the structure registered
  // at the rotation consensus of 80 m: 15 of 16 ok, median 0.112 m, max 0.240 m, rotation max
  // 0.57 deg (frame 0, rejected). With the truth at the trigger times (2026-12-06): 13 of 16
  // ok, median 0.189 m, max 0.387 m, rotation max 0.60 deg (frames 0-20 rejected); the errors
  // grow from 0.05 m at frame 60 to 0.23 m at the end, the VO's scale falling by 3 % per 10 m, a
  // residual radial distortion of the rectified images (README): the earlier truth's lag made up
  // for part of it. Asserted with a margin.
  KittiImportOptions cam0_noisy = cam1_all;
  cam0_noisy.camera = 0;
  cam0_noisy.seed = 2;
  cam0_noisy.out_dir = dir / "cam0_noisy";
  const Drive cam0_whole = ImportKitti(cam0_noisy);
  WriteDrive(CorrectDriveTrack(cam0_whole, track_frame, track), dir / "cam0_noisy_lidar");
  AnchorInputs cam0_inputs = lidar_inputs;
  cam0_inputs.drive_dir = dir / "cam0_noisy_lidar";
  const Drive cam0_lidar_drive = LoadDrive(cam0_inputs.drive_dir);
  const Figures other =
      run_on(cam0_inputs, cam0_lidar_drive,
             VoStructure::FromResult(RunVisualOdometry(cam0_lidar_drive, VoOptions())), options,
             "camera 0, LiDAR-consistent track");
  ASSERT_GE(other.horizontal.size() * 4, other.anchors * 3);
  EXPECT_GE(other.ok * 4, static_cast<int>(other.anchors) * 3);
  EXPECT_LE(other.ok_max_horizontal, 0.4);
  EXPECT_LE(Median(other.horizontal), 0.22);
  EXPECT_LE(*std::max_element(other.horizontal.begin(), other.horizontal.end()), 0.5);
}

}  // namespace
}  // namespace epiloc
