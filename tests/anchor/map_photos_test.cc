// Map photographs on the synthetic world: anchoring against them, projective texturing, bad input.
#include "epiloc/anchor/map_photos.h"

#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "epiloc/anchor/anchor.h"
#include "epiloc/cloud/cloud_io.h"

namespace epiloc {
namespace {

// Query frames (3 m GNSS, 5 deg heading error, other lane, lens distortion) anchored against the
// survey's photographs lifted onto the simulated LiDAR map.
TEST(MapPhotos, AnchorsSyntheticQueryFramesToCentimetres) {
  const std::string world = SharedSyntheticWorld();
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.every = 4;
  inputs.photos_dir = world + "/survey";
  AnchorOptions options;
  options.prior.camera_height_m = 1.5;  // DriveOptions::Query()
  options.heading_error_deg = 5.0;
  const AnchorDriveResult result = AnchorDrive(inputs, options);
  const Drive drive = LoadDrive(inputs.drive_dir);
  const EnuFrame enu(inputs.map_origin);
  ASSERT_GE(result.frames.size(), 5u);
  double max_position = 0, max_rotation = 0;
  for (const AnchorResult& r : result.frames) {
    ASSERT_EQ(r.status, AnchorStatus::kOk) << "frame " << r.frame << ": " << r.message;
    const auto truth = TrueMapFromCam(drive, r.timestamp_s, enu);
    ASSERT_TRUE(truth);
    const Rigid3d& true_pose = *truth;
    max_position =
        std::max(max_position, (r.map_from_cam.translation - true_pose.translation).norm());
    max_rotation =
        std::max(max_rotation, RotationDifferenceDeg(r.map_from_cam.rotation, true_pose.rotation));
  }
  EXPECT_LE(max_position, 0.05);
  EXPECT_LE(max_rotation, 0.1);
}

// Where no photograph is near (here: none within 1 cm), the map is rendered instead: the frames
// still anchor, as without photographs.
TEST(MapPhotos, FallsBackToRenderingsWhereNoPhotographIsNear) {
  const std::string world = SharedSyntheticWorld();
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.frames = {0, 8, 16};
  inputs.photos_dir = world + "/survey";
  inputs.photos.max_view_distance_m = 0.01;
  AnchorOptions options;
  options.prior.camera_height_m = 1.5;
  const AnchorDriveResult result = AnchorDrive(inputs, options);
  ASSERT_EQ(result.frames.size(), 3u);
  EXPECT_EQ(result.num_ok, 3) << result.frames[0].message;
}

// Textured at a photograph's own pose, a rendering reproduces the photograph wherever the map
// has geometry: every pixel's point projects back onto its own pixel.
TEST(MapPhotos, TextureAtAPhotographsPoseReproducesIt) {
  const std::string world = SharedSyntheticWorld();
  const EnuFrame enu(SynthOrigin());
  const MapPhotos photos(world + "/survey", enu, MapPhotoOptions());
  ASSERT_GT(photos.size(), 10);
  const int index = photos.size() / 2;
  const Rigid3d cam_from_map = photos.map_from_photo(index).Inverse();
  const PointCloud map = ReadPointCloud(world + "/lidar/map.ply");
  CloudRenderOptions render_options;
  CloudRenderResult render = RenderCloud(map, photos.camera(), cam_from_map, render_options);
  MapPhotoCache cache(photos, map, render_options);
  EXPECT_EQ(photos.Nearest(photos.map_from_photo(index)).front(), index);
  const cv::Mat mask = cache.Texture(photos.camera(), cam_from_map, &render);
  const cv::Mat photo = photos.Read(index);
  ASSERT_EQ(render.image.size(), photo.size());
  const int textured = cv::countNonZero(mask);
  EXPECT_GT(textured, static_cast<int>(0.2 * mask.total()));
  cv::Mat difference;
  cv::absdiff(render.image, photo, difference);
  EXPECT_LE(cv::norm(difference, cv::NORM_INF, mask), 1.0);
  EXPECT_EQ(cv::countNonZero((render.image > 0) & ~mask), 0);  // untextured pixels stay black
}

TEST(MapPhotos, RejectsDrivesWithoutCameraOrientations) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  Drive drive = LoadDrive(world + "/query");
  drive.ground_truth.reset();
  for (PositionSample& s : drive.gnss.samples) s.enu_from_cam.reset();
  WriteDrive(drive, dir / "unposed");
  ExpectError([&] { MapPhotos(dir / "unposed", EnuFrame(SynthOrigin()), MapPhotoOptions()); },
              {"unposed", "orientations"});
  MapPhotoOptions bad;
  bad.max_views = 0;
  ExpectError([&] { MapPhotos(world + "/survey", EnuFrame(SynthOrigin()), bad); },
              {"max_views"});
  ExpectError([&] { MapPhotos(dir / "missing", EnuFrame(SynthOrigin()), MapPhotoOptions()); },
              {"missing"});
}

}  // namespace
}  // namespace epiloc
