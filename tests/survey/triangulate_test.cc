#include "epiloc/survey/triangulate.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "anchor/anchor_test_util.h"
#include "epiloc/db/database.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/survey/build_db.h"
#include "epiloc/synth/render.h"
#include "test_util.h"

namespace epiloc {
namespace {

constexpr double kPi = 3.14159265358979323846;

Camera TestCamera() {
  Camera camera;
  camera.width = 800;
  camera.height = 400;
  camera.fx = camera.fy = 600.0;
  camera.cx = 399.5;
  camera.cy = 199.5;
  return camera;
}

// Camera looking north (x east, y down, z north) turned by `yaw_deg` about up, at `center`.
Eigen::Quaterniond EnuFromCam(double yaw_deg) {
  Eigen::Matrix3d looking_north;
  looking_north.col(0) = Eigen::Vector3d::UnitX();
  looking_north.col(1) = -Eigen::Vector3d::UnitZ();
  looking_north.col(2) = Eigen::Vector3d::UnitY();
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * kPi / 180.0, Eigen::Vector3d::UnitZ()) *
                            looking_north);
}

Rigid3d CamFromWorld(const Eigen::Quaterniond& enu_from_cam, const Eigen::Vector3d& center) {
  const Eigen::Quaterniond cam_from_enu = enu_from_cam.conjugate();
  return Rigid3d(cam_from_enu, -(cam_from_enu * center));
}

Eigen::Vector2d Project(const Camera& camera,
                        const Rigid3d& cam_from_world,
                        const Eigen::Vector3d& x) {
  const Eigen::Vector3d p = cam_from_world * x;
  return {camera.fx * p.x() / p.z() + camera.cx, camera.fy * p.y() / p.z() + camera.cy};
}

// Far from the origin, as a long drive's ENU coordinates are.
const Eigen::Vector3d kFar(3000.0, 5000.0, 100.0);

TEST(TriangulateTrack, ExactProjectionsGiveThePoint) {
  std::mt19937 rng(11);
  // Off the focus of expansion, so the rays of 6 m of forward motion meet at >= 4 degrees.
  std::uniform_real_distribution<double> lateral(4.0, 10.0), height(-1.5, 5.0), ahead(12.0, 30.0);
  std::uniform_real_distribution<double> yaw(-3.0, 3.0);
  std::bernoulli_distribution left(0.5);
  const Camera camera = TestCamera();
  const TriangulateOptions options;
  int checked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const double x = left(rng) ? -lateral(rng) : lateral(rng);
    const Eigen::Vector3d point = kFar + Eigen::Vector3d(x, ahead(rng), height(rng));
    std::vector<TrackObservation> observations;
    for (int k = 0; k < 4; ++k) {
      const Rigid3d pose =
          CamFromWorld(EnuFromCam(yaw(rng)), kFar + Eigen::Vector3d(0, 2.0 * k, 0));
      observations.push_back({pose, Project(camera, pose, point)});
    }
    const TrackTriangulation result = TriangulateTrack(observations, camera, options);
    ASSERT_TRUE(result.valid) << "trial " << trial;
    EXPECT_LT((result.point_in_world - point).norm(), 1e-6) << "trial " << trial;
    EXPECT_LT(result.rms_error_px, 1e-6);
    EXPECT_THAT(result.inlier_mask, ::testing::Each(1));
    ++checked;
  }
  EXPECT_EQ(checked, 200);
}

TEST(TriangulateTrack, WrongObservationDroppedOthersKept) {
  const Camera camera = TestCamera();
  const Eigen::Vector3d point = kFar + Eigen::Vector3d(3.0, 20.0, 1.0);
  std::vector<TrackObservation> observations;
  for (int k = 0; k < 5; ++k) {
    const Rigid3d pose = CamFromWorld(EnuFromCam(0.0), kFar + Eigen::Vector3d(0, 1.5 * k, 0));
    observations.push_back({pose, Project(camera, pose, point)});
  }
  observations[2].pixel += Eigen::Vector2d(25.0, -40.0);  // a wrong match
  const TrackTriangulation result = TriangulateTrack(observations, camera, TriangulateOptions());
  ASSERT_TRUE(result.valid);
  EXPECT_EQ(result.inlier_mask, (std::vector<char>{1, 1, 0, 1, 1}));
  EXPECT_LT((result.point_in_world - point).norm(), 1e-6);
}

TEST(TriangulateTrack, RejectsBadGeometry) {
  const Camera camera = TestCamera();
  const TriangulateOptions options;  // 0.75 degrees, depth 0.5..150 m, 2 px
  const Rigid3d a = CamFromWorld(EnuFromCam(0.0), kFar);
  const Rigid3d b = CamFromWorld(EnuFromCam(0.0), kFar + Eigen::Vector3d(0.0, 1.0, 0.0));
  // Two rays at 0.6 degrees: too little parallax.
  const Eigen::Vector3d far_point = kFar + Eigen::Vector3d(0.3, 60.0, 0.0);
  EXPECT_FALSE(
      TriangulateTrack({{a, Project(camera, a, far_point)}, {b, Project(camera, b, far_point)}},
                       camera, options)
          .valid);
  // A wrong match of two views: no point explains both within 2 px.
  const Eigen::Vector3d point = kFar + Eigen::Vector3d(4.0, 12.0, 1.0);
  EXPECT_FALSE(TriangulateTrack({{a, Project(camera, a, point)},
                                 {b, Project(camera, b, point) + Eigen::Vector2d(0.0, 30.0)}},
                                camera, options)
                   .valid);
  // The same point seen by both, but behind the range of max_depth_m.
  TriangulateOptions near_only = options;
  near_only.max_depth_m = 10.0;
  EXPECT_FALSE(TriangulateTrack({{a, Project(camera, a, point)}, {b, Project(camera, b, point)}},
                                camera, near_only)
                   .valid);
  EXPECT_TRUE(TriangulateTrack({{a, Project(camera, a, point)}, {b, Project(camera, b, point)}},
                               camera, options)
                  .valid);
}

TEST(TriangulateOptions, CheckNamesTheField) {
  TriangulateOptions options;
  options.min_observations = 1;
  ExpectError([&] { options.Check(); }, {"min_observations"});
  options = TriangulateOptions();
  options.max_depth_m = 0.1;
  ExpectError([&] { options.Check(); }, {"max_depth_m"});
}

// A database of exactly projected random points with a distinct random descriptor each; in one
// frame the descriptors of some features are swapped (wrong matches). One frame has no
// orientation.
struct SyntheticDb {
  std::vector<Eigen::Vector3d> points_in_enu;
  std::map<std::pair<image_t, int>, int> truth;  // (image, feature) -> index of the point
  std::vector<std::pair<image_t, int>> swapped;  // features carrying another point's descriptor
};

SyntheticDb WriteSyntheticDb(Database& db) {
  SyntheticDb s;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> lateral(-10.0, 10.0), height(-1.5, 6.0), ahead(10.0, 45.0),
      yaw(-2.0, 2.0);
  std::uniform_int_distribution<int> byte(0, 255);
  const Camera camera = TestCamera();
  db.SetEnuOrigin(Geodetic{49.0, 8.4, 110.0});
  DbCamera db_camera;
  db_camera.camera = db_camera.original = camera;
  DbDrive drive;
  drive.name = "synthetic";
  drive.camera_id = db.WriteCamera(db_camera);
  drive.drive_id = db.WriteDrive(drive);

  const int num_points = 400;
  FeatureDescriptors point_descriptors(num_points, 128);
  for (int p = 0; p < num_points; ++p) {
    s.points_in_enu.push_back(kFar + Eigen::Vector3d(lateral(rng), ahead(rng), height(rng)));
    for (int c = 0; c < 128; ++c) point_descriptors(p, c) = static_cast<uint8_t>(byte(rng));
  }
  for (int f = 0; f < 9; ++f) {
    DbFrame frame;
    frame.drive_id = drive.drive_id;
    frame.frame = f;
    frame.timestamp_s = f;
    frame.center_in_enu = kFar + Eigen::Vector3d(0.2 * std::sin(f), 1.5 * f, 0.0);
    const Eigen::Quaterniond enu_from_cam = EnuFromCam(yaw(rng));
    if (f != 8) frame.enu_from_cam = enu_from_cam;
    const Rigid3d pose = CamFromWorld(enu_from_cam, frame.center_in_enu);
    std::vector<int> seen;
    std::vector<Eigen::Vector2d> pixels;
    for (int p = 0; p < num_points; ++p) {
      if ((pose * s.points_in_enu[p]).z() < 1.0) continue;
      const Eigen::Vector2d pixel = Project(camera, pose, s.points_in_enu[p]);
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() > camera.width - 1 ||
          pixel.y() > camera.height - 1) {
        continue;
      }
      seen.push_back(p);
      pixels.push_back(pixel);
    }
    FeatureKeypoints keypoints(seen.size(), 4);
    FeatureDescriptors descriptors(seen.size(), 128);
    for (size_t k = 0; k < seen.size(); ++k) {
      keypoints.row(k) << static_cast<float>(pixels[k].x()), static_cast<float>(pixels[k].y()),
          4.0f, 0.0f;
      descriptors.row(k) = point_descriptors.row(seen[k]);
    }
    if (f == 3) {  // 20 pairs of features swap descriptors
      for (int k = 0; k + 1 < 40; k += 2) descriptors.row(k).swap(descriptors.row(k + 1));
    }
    const image_t image_id = db.WriteFrame(frame, keypoints, descriptors);
    for (size_t k = 0; k < seen.size(); ++k) s.truth[{image_id, static_cast<int>(k)}] = seen[k];
    if (f == 3) {
      for (int k = 0; k < 40; ++k) s.swapped.emplace_back(image_id, k);
    }
  }
  return s;
}

TEST(TriangulateDatabase, SyntheticFramesGiveTheTruePointsAndRejectWrongMatches) {
  Database db(":memory:");
  const SyntheticDb s = WriteSyntheticDb(db);
  TriangulateOptions options;
  options.num_threads = 2;
  const TriangulateSummary summary = TriangulateDatabase(db, options);
  EXPECT_EQ(summary.num_drives, 1);
  EXPECT_EQ(summary.num_frames, 8);
  EXPECT_EQ(summary.frames_without_orientation, 1);
  EXPECT_EQ(summary.num_points, db.NumPoints());
  EXPECT_EQ(summary.num_observations, db.NumObservations());
  EXPECT_GT(summary.num_points, 300);  // of 400, most seen by >= 2 frames at >= 0.75 degrees
  EXPECT_LT(summary.num_epipolar_inliers, summary.num_matches);  // swapped ones rejected
  EXPECT_LT(summary.mean_error_px, 1e-3);

  // Every observation belongs to the point's true source; the position matches it (keypoints
  // are float32: ~1e-5 px, so ~1e-5 m at these depths).
  std::map<int64_t, std::vector<std::pair<image_t, int>>> by_point;
  std::map<int64_t, Eigen::Vector3d> position;
  for (const DbFrame& frame : db.ReadFrames()) {
    for (const DbFramePoint& p : db.ReadFramePoints(frame.image_id)) {
      by_point[p.point_id].emplace_back(frame.image_id, p.feature_index);
      position[p.point_id] = p.position_in_enu;
    }
  }
  ASSERT_EQ(static_cast<int64_t>(by_point.size()), summary.num_points);
  int64_t swapped_observations = 0;
  for (const auto& [point_id, observations] : by_point) {
    const int source = s.truth.at(observations.front());
    for (const auto& observation : observations) {
      EXPECT_EQ(s.truth.at(observation), source) << "point " << point_id;
      swapped_observations += std::count(s.swapped.begin(), s.swapped.end(), observation);
    }
    EXPECT_LT((position[point_id] - s.points_in_enu[source]).norm(), 1e-4) << "point " << point_id;
  }
  EXPECT_EQ(swapped_observations, 0);
}

TEST(TriangulateDatabase, RerunReplacesThePoints) {
  TempDir dir;
  const std::string path = dir / "route.sqlite";
  int64_t points = 0, observations = 0;
  {
    Database db(path);
    WriteSyntheticDb(db);
    const TriangulateSummary first = TriangulateDatabase(db, TriangulateOptions());
    points = db.NumPoints();
    observations = db.NumObservations();
    EXPECT_EQ(first.num_points, points);
    EXPECT_GT(points, 0);
  }
  Database db(path);  // reopened: the points persisted
  EXPECT_EQ(db.NumPoints(), points);
  const TriangulateSummary second = TriangulateDatabase(db, TriangulateOptions());
  EXPECT_EQ(second.num_points, points);
  EXPECT_EQ(db.NumPoints(), points);
  EXPECT_EQ(db.NumObservations(), observations);
  // Invalid options change nothing.
  TriangulateOptions bad;
  bad.max_reprojection_error_px = -1.0;
  ExpectError([&] { TriangulateDatabase(db, bad); }, {"max_reprojection_error_px"});
  EXPECT_EQ(db.NumPoints(), points);
}

// The survey of the shared synthetic street (exact ground-truth poses): built into a database
// with triangulation, each point compared with the exact renderer's depth where the point
// projects in the frames that observe it.
TEST(TriangulateDatabase, SyntheticWorldPointsLieOnTheSurfaces) {
  const std::string world_dir = SharedSyntheticWorld();
  TempDir dir;
  const std::string db_path = dir / "route.sqlite";
  BuildDbOptions build;
  build.num_threads = 2;
  build.retrieval_index = false;
  const BuildDbSummary built = BuildDatabase(world_dir + "/survey", db_path, build);
  ASSERT_TRUE(built.triangulated);
  const TriangulateSummary& summary = built.triangulation;
  EXPECT_GT(summary.num_points, 1000);
  EXPECT_GT(summary.mean_track_length, 2.5);
  EXPECT_LT(summary.mean_error_px, 0.5);

  SynthOptions synth;  // as SharedSyntheticWorld generates it
  synth.length_m = 50.0;
  synth.seed = 3;
  const World world = BuildWorld(synth.ResolvedWorldOptions());
  const EnuFrame world_enu(world.origin());

  Database db(db_path, Database::Mode::kReadOnly);
  const EnuFrame db_enu(*db.EnuOrigin());
  const DbDrive drive = db.ReadDrives().front();
  const Camera camera = db.ReadCamera(drive.camera_id).camera;
  RenderOptions render;
  render.depth = true;
  const Renderer renderer(camera, render);
  std::vector<double> relative_errors, signed_errors;
  const std::vector<DbFrame> frames = db.ReadFrames();
  for (size_t i = 0; i < frames.size(); i += 3) {
    const DbFrame& frame = frames[i];
    ASSERT_TRUE(frame.enu_from_cam);
    const Eigen::Matrix3d world_from_cam = world_enu.EnuFromLocalEnu(frame.position) *
                                           db_enu.EnuFromLocalEnu(frame.position).transpose() *
                                           frame.enu_from_cam->toRotationMatrix();
    const Rigid3d pose = CamFromWorld(Eigen::Quaterniond(world_from_cam).normalized(),
                                      world_enu.ToEnu(frame.position));
    const cv::Mat depth = renderer.Render(world, pose).depth;
    for (const DbFramePoint& p : db.ReadFramePoints(frame.image_id)) {
      const Eigen::Vector3d x_cam = pose * world_enu.ToEnu(db_enu.ToGeodetic(p.position_in_enu));
      const Eigen::Vector2d pixel(camera.fx * x_cam.x() / x_cam.z() + camera.cx,
                                  camera.fy * x_cam.y() / x_cam.z() + camera.cy);
      // Bilinear: on the road seen at a grazing angle the depth changes by percents per pixel.
      const int u = static_cast<int>(std::floor(pixel.x()));
      const int v = static_cast<int>(std::floor(pixel.y()));
      ASSERT_TRUE(u >= 0 && v >= 0 && u + 1 < depth.cols && v + 1 < depth.rows)
          << pixel.transpose();
      const double a = pixel.x() - u, b = pixel.y() - v;
      const double d00 = depth.at<float>(v, u), d01 = depth.at<float>(v, u + 1);
      const double d10 = depth.at<float>(v + 1, u), d11 = depth.at<float>(v + 1, u + 1);
      const double rendered = (1 - b) * ((1 - a) * d00 + a * d01) + b * ((1 - a) * d10 + a * d11);
      const bool sky = std::min({d00, d01, d10, d11}) <= 0.0;
      relative_errors.push_back(sky ? 1.0 : std::abs(x_cam.z() - rendered) / rendered);
      if (!sky) signed_errors.push_back((x_cam.z() - rendered) / rendered);
    }
  }
  ASSERT_GT(relative_errors.size(), 300u);
  std::sort(relative_errors.begin(), relative_errors.end());
  std::sort(signed_errors.begin(), signed_errors.end());
  const double median = relative_errors[relative_errors.size() / 2];
  const double p90 = relative_errors[relative_errors.size() * 9 / 10];
  const double bias = signed_errors[signed_errors.size() / 2];
  std::printf(
      "%zu point views: relative depth error median %.5f, 90th percentile %.5f, signed "
      "median %.5f; mean reprojection error %.3f px, mean track length %.2f\n",
      relative_errors.size(), median, p90, bias, summary.mean_error_px, summary.mean_track_length);
  // 0.2 px of feature noise over rays meeting at >= 0.75 degrees: ~2 % along the ray at worst.
  EXPECT_LT(median, 0.01);
  EXPECT_LT(p90, 0.05);
  EXPECT_LT(std::abs(bias), 0.002);  // no scale or pose-convention error
}

}  // namespace
}  // namespace epiloc
