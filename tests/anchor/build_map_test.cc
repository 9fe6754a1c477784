#include "epiloc/anchor/build_map.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/kitti.h"
#include "test_util.h"

namespace epiloc {
namespace {

// Per-scan files (sensor frame) merged with their poses give back the world-frame map the
// simulator wrote, point for point; colouring from the survey frames gives the texture colours.
TEST(BuildMap, MergesSyntheticScansIntoTheWorldFrameAndColoursThem) {
  const std::string world = SharedSyntheticWorld();
  const PointCloud reference = ReadPointCloud(world + "/lidar/map.ply");
  TempDir dir;
  BuildMapOptions options;
  options.voxel_m = 0.0;
  options.min_range_m = 0.0;   // the simulator keeps hits from 1 m ...
  options.max_range_m = 1e3;   // ... up to 80 m before its range noise is added
  options.colorize = true;
  options.colour.keep_uncoloured = true;
  const std::string out = dir / "map.ply";
  const BuildMapSummary summary =
      BuildMap(world + "/survey", out, SynthOrigin(), "world origin", options);
  EXPECT_EQ(summary.num_points_in, static_cast<int64_t>(reference.size()));
  EXPECT_EQ(summary.num_points_out, static_cast<int64_t>(reference.size()));
  EXPECT_GT(summary.num_colour_frames, 10);

  const PointCloud map = ReadPointCloud(out);
  ASSERT_EQ(map.size(), reference.size());
  ASSERT_TRUE(map.HasColour());
  ASSERT_TRUE(map.HasIntensity());
  double max_offset = 0.0, colour_error = 0.0;
  int64_t coloured = 0;
  for (size_t i = 0; i < map.size(); ++i) {
    max_offset = std::max(max_offset, double((map.positions[i] - reference.positions[i]).norm()));
    EXPECT_NEAR(map.intensity[i], reference.intensity[i], 1e-6);
    if (map.rgb[i] == std::array<uint8_t, 3>{128, 128, 128}) continue;  // unseen
    ++coloured;
    for (int c = 0; c < 3; ++c) colour_error += std::abs(map.rgb[i][c] - reference.rgb[i][c]);
  }
  EXPECT_LT(max_offset, 1e-3);
  EXPECT_GT(coloured, static_cast<int64_t>(map.size()) / 2);
  // Colours come from rendered frames (filtered, area-averaged), not the exact texture texels.
  EXPECT_LT(colour_error / (3.0 * coloured), 20.0);

  const MapSidecar sidecar = ReadMapSidecar(SidecarPath(out));
  EXPECT_EQ(sidecar.enu_origin.lat_deg, SynthOrigin().lat_deg);
  EXPECT_EQ(sidecar.origin_source, "world origin");
  EXPECT_EQ(sidecar.num_points, static_cast<int64_t>(map.size()));
  EXPECT_EQ(sidecar.num_scans, summary.num_scans);
  EXPECT_EQ(sidecar.attributes, (std::vector<std::string>{"intensity", "rgb"}));
  EXPECT_EQ(sidecar.colour_mode, "closest");
  EXPECT_FALSE(sidecar.bounds.Empty());
}

TEST(BuildMap, VoxelFiltersAndDefaultsToTheDrivesFirstPosition) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  BuildMapOptions options;
  options.voxel_m = 0.2;
  const std::string out = dir / "map.pcd";
  const BuildMapSummary summary = BuildMap(world + "/survey", out, std::nullopt, "", options);
  EXPECT_LT(summary.num_points_out, summary.num_points_in / 2);
  const MapSidecar sidecar = ReadMapSidecar(SidecarPath(out));
  const Drive survey = LoadDrive(world + "/survey");
  EXPECT_EQ(sidecar.enu_origin.lat_deg, survey.ground_truth->samples.front().position.lat_deg);
  EXPECT_THAT(sidecar.origin_source, ::testing::HasSubstr("first ground-truth position"));
  EXPECT_EQ(sidecar.voxel_m, 0.2);
  EXPECT_EQ(sidecar.attributes, (std::vector<std::string>{"intensity"}));
  EXPECT_EQ(ReadPointCloud(out).size(), static_cast<size_t>(summary.num_points_out));
}

// The synthetic survey's scan poses are exact: its scans agree best unstretched. With the
// scans' positions drawn 3 % nearer the first scan (a track too short, as a GNSS track with slow
// errors can be), shared surfaces are drawn apart and the check finds the stretch back.
TEST(BuildMap, TrackScaleCheckFindsTheStretchTheScansAgreeWith) {
  const std::string world = SharedSyntheticWorld();
  Drive survey = LoadDrive(world + "/survey");
  ASSERT_GE(survey.lidar.size(), 4u);
  const EnuFrame frame(SynthOrigin());
  BuildMapOptions options;
  const TrackScaleCheck exact = CheckTrackScale(survey, frame, options);
  EXPECT_EQ(exact.num_scans, static_cast<int64_t>(survey.lidar.size()));
  EXPECT_GT(exact.span_m, 30.0);
  ASSERT_EQ(exact.factors.size(), exact.thickness_m.size());
  ASSERT_EQ(exact.factors.size(), exact.shared_voxels.size());
  EXPECT_EQ(exact.factors.size(), 25u);  // 0.94 .. 1.06 by 0.005
  EXPECT_NEAR(exact.best_factor, 1.0, 0.005);

  const Eigen::Vector3d first = frame.ToEnu(survey.lidar.front().sensor_position);
  for (LidarScan& scan : survey.lidar) {
    Eigen::Vector3d x = frame.ToEnu(scan.sensor_position);
    x.head<2>() = first.head<2>() + (x - first).head<2>() / 1.03;
    scan.sensor_position = frame.ToGeodetic(x);
  }
  const TrackScaleCheck shortened = CheckTrackScale(survey, frame, options);
  EXPECT_NEAR(shortened.best_factor, 1.03, 0.005);
  // The shared surfaces are thicker off the best stretch on either side.
  const auto at = [&](double f) {
    for (size_t i = 0; i < shortened.factors.size(); ++i) {
      if (std::abs(shortened.factors[i] - f) < 1e-9) return shortened.thickness_m[i];
    }
    return -1.0;
  };
  EXPECT_GT(at(1.0), at(1.03));
  EXPECT_GT(at(1.06), at(1.03));

  // Bad input.
  ExpectError([&] { CheckTrackScale(survey, frame, options, 0.0); }, {"max_stretch"});
  ExpectError([&] { CheckTrackScale(survey, frame, options, 0.06, 0.1); }, {"step"});
  ExpectError([&] { CheckTrackScale(LoadDrive(world + "/query"), frame, options); },
              {"no LiDAR scans"});
}

// The shared KITTI drive's OXTS track (fused with the unit's velocity, as imported) is shorter
// than its LiDAR says: the scans agree best with the track stretched by 3.5-4 % (and the
// unit's own speed integrates to about 3 % more than its positions' steps). Recorded here so that
// an import that fixes it, or one that makes it worse, is noticed.
TEST(BuildMap, TrackScaleCheckOnTheSharedKittiDrive) {
  namespace fs = std::filesystem;
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  KittiImportOptions import;
  import.raw_drive_dir = raw.string();
  const Drive drive = ImportKitti(import);
  ASSERT_FALSE(drive.lidar.empty());
  const TrackScaleCheck check =
      CheckTrackScale(drive, EnuFrame(drive.lidar.front().sensor_position), BuildMapOptions());
  std::printf("KITTI track scale check: best stretch %.4f over %.1f m\n", check.best_factor,
              check.span_m);
  EXPECT_GT(check.best_factor, 1.025);
  EXPECT_LT(check.best_factor, 1.05);
}

TEST(BuildMap, RejectsBadInput) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  // The query drive has no LiDAR scans.
  ExpectError([&] { BuildMap(world + "/query", dir / "m.ply", std::nullopt, "", {}); },
              {"query", "no LiDAR scans"});
  BuildMapOptions options;
  options.voxel_m = -1;
  ExpectError([&] { BuildMap(world + "/survey", dir / "m.ply", std::nullopt, "", options); },
              {"--voxel must be >= 0"});
  ExpectError([&] { BuildMap(world + "/survey", dir / "m.las", std::nullopt, "", {}); }, {"las"});
  ExpectError([&] { ParseColourMode("median"); }, {"unknown colour mode 'median'"});
  // A scan file that is not a point cloud is named.
  TempDir copy;
  Drive drive = LoadDrive(world + "/survey");
  WriteText(copy / "broken.ply", "this is not a point cloud\n");
  drive.lidar.resize(1);
  drive.lidar[0].path = copy / "broken.ply";
  WriteDrive(drive, copy / "drive");
  ExpectError([&] { BuildMap(copy / "drive", dir / "m.ply", std::nullopt, "", {}); },
              {"broken.ply"});
}

}  // namespace
}  // namespace epiloc
