#include "epiloc/anchor/anchor.h"

#include <random>

#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "epiloc/cloud/cloud_io.h"
#include "test_util.h"

namespace epiloc {
namespace {

AnchorInputs SyntheticInputs(const std::string& world) {
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.every = 4;
  return inputs;
}

AnchorOptions SyntheticOptions() {
  AnchorOptions options;
  options.prior.camera_height_m = 1.5;  // DriveOptions::Query()
  return options;
}

// Query frames (3 m GNSS, distorted dashcam, other lane) anchored in the simulated LiDAR map.
TEST(Anchor, AnchorsSyntheticQueryFramesToCentimetres) {
  const std::string world = SharedSyntheticWorld();
  const AnchorInputs inputs = SyntheticInputs(world);
  AnchorOptions options = SyntheticOptions();
  options.heading_error_deg = 5.0;
  int64_t progress_calls = 0;
  const AnchorDriveResult result =
      AnchorDrive(inputs, options, [&](int64_t, int64_t) { ++progress_calls; });
  const Drive drive = LoadDrive(inputs.drive_dir);
  ASSERT_GE(result.frames.size(), 5u);
  EXPECT_EQ(progress_calls, static_cast<int64_t>(result.frames.size()));
  EXPECT_EQ(result.num_ok, static_cast<int64_t>(result.frames.size()));
  double max_position = 0, max_rotation = 0;
  for (const AnchorResult& r : result.frames) {
    ASSERT_EQ(r.status, AnchorStatus::kOk) << "frame " << r.frame << ": " << r.message;
    const auto true_pose = TrueMapFromCam(drive, r.timestamp_s, EnuFrame(inputs.map_origin));
    ASSERT_TRUE(true_pose);
    const Rigid3d& truth = *true_pose;
    max_position = std::max(max_position, (r.map_from_cam.translation - truth.translation).norm());
    max_rotation =
        std::max(max_rotation, RotationDifferenceDeg(r.map_from_cam.rotation, truth.rotation));
    EXPECT_GE(r.num_inliers, options.min_inliers);
    EXPECT_LE(r.rmse_px, options.max_rmse_px);
    // The reported WGS-84 pose is the map pose.
    const EnuFrame enu(inputs.map_origin);
    EXPECT_LT((enu.ToEnu(r.position) - r.map_from_cam.translation).norm(), 1e-6);
    const Eigen::Matrix3d local = enu.EnuFromLocalEnu(r.position).transpose() *
                                  r.map_from_cam.rotation.toRotationMatrix();
    EXPECT_LT(RotationDifferenceDeg(Eigen::Quaterniond(local), r.enu_from_cam), 1e-6);
  }
  EXPECT_LE(max_position, 0.05);
  EXPECT_LE(max_rotation, 0.1);
}

TEST(Anchor, FramesTheMapDoesNotCoverGetAStatus) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  // A small cloud 300 m north of the street: near enough to pass the frame check, never in view.
  PointCloud far;
  for (int i = 0; i < 2000; ++i) {
    far.positions.emplace_back(static_cast<float>(i % 40), 300.0f + static_cast<float>(i / 40),
                               0.0f);
  }
  WritePointCloud(dir / "far.ply", far);
  AnchorInputs inputs = SyntheticInputs(world);
  inputs.cloud_path = dir / "far.ply";
  inputs.frames = {0};
  const AnchorDriveResult result = AnchorDrive(inputs, SyntheticOptions());
  ASSERT_EQ(result.frames.size(), 1u);
  EXPECT_EQ(result.frames[0].status, AnchorStatus::kNoCoverage);
  EXPECT_THAT(result.frames[0].message, ::testing::HasSubstr("does not cover"));
  EXPECT_FALSE(result.frames[0].has_pose);
  EXPECT_EQ(result.num_ok, 0);
}

TEST(Anchor, RejectsBadInputWithClearErrors) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  AnchorInputs inputs = SyntheticInputs(world);
  inputs.frames = {0};

  // A cloud placed in another frame: its origin 110 km away from the drive.
  AnchorInputs wrong_frame = inputs;
  wrong_frame.map_origin = {48.0, 8.4, 115.0};
  ExpectError([&] { AnchorDrive(wrong_frame, SyntheticOptions()); },
              {"map.ply", "another frame"});

  // A file that is not a point cloud.
  AnchorInputs not_a_cloud = inputs;
  not_a_cloud.cloud_path = dir / "notes.ply";
  WriteText(not_a_cloud.cloud_path, "these are my notes\n");
  ExpectError([&] { AnchorDrive(not_a_cloud, SyntheticOptions()); }, {"notes.ply"});
  AnchorInputs missing = inputs;
  missing.cloud_path = dir / "missing.ply";
  ExpectError([&] { AnchorDrive(missing, SyntheticOptions()); }, {"missing.ply"});

  // A frame the drive does not have.
  AnchorInputs no_frame = inputs;
  no_frame.frames = {99999};
  ExpectError([&] { AnchorDrive(no_frame, SyntheticOptions()); }, {"frame 99999"});

  // Images whose size differs from the calibration.
  Drive drive = LoadDrive(inputs.drive_dir);
  drive.camera.width = 800;
  drive.camera.cx = 399.5;
  WriteDrive(drive, dir / "bad_calibration");
  AnchorInputs bad_calibration = inputs;
  bad_calibration.drive_dir = dir / "bad_calibration";
  ExpectError([&] { AnchorDrive(bad_calibration, SyntheticOptions()); },
              {"000000.png", "differs from the calibration"});

  // A shading the map cannot give, and invalid options.
  AnchorInputs intensity_only = inputs;
  PointCloud grey = ReadPointCloud(inputs.cloud_path);
  grey.rgb.clear();
  WritePointCloud(dir / "grey.ply", grey);
  intensity_only.cloud_path = dir / "grey.ply";
  AnchorOptions colour = SyntheticOptions();
  colour.render.shading = RenderShading::kColour;
  ExpectError([&] { AnchorDrive(intensity_only, colour); }, {"grey.ply", "coloured map"});
  AnchorOptions bad = SyntheticOptions();
  bad.heading_error_deg = -1;
  ExpectError([&] { AnchorDrive(inputs, bad); }, {"--heading-error-deg"});
  bad = SyntheticOptions();
  bad.min_inliers = 5;
  ExpectError([&] { bad.Check(); }, {"--min-inliers"});
  ExpectError([] { ParseFeatureType("orb"); }, {"unknown matcher 'orb'"});
  ExpectError([] { ParseRenderShading("phong"); }, {"unknown shading 'phong'"});
}

}  // namespace
}  // namespace epiloc
