#include "epiloc/synth/lidar.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/trajectory.h"

namespace epiloc {
namespace {

World SmallWorld() {
  WorldOptions o;
  o.length_m = 80;
  o.margin_after_m = 60;
  o.seed = 4;
  return BuildWorld(o);
}

TEST(Lidar, PointsLieOnTheirSurfacesWithinTheRangeNoise) {
  const World world = SmallWorld();
  LidarOptions options;
  const DrivePath path(world, DriveOptions::Survey(), world.options.length_m, 1);
  const Rigid3d sensor = path.WorldFromSensorAtS(20.0, options.sensor_height_m);
  const std::vector<LidarPoint> points = SimulateScan(world, sensor, options, 9);
  ASSERT_GT(points.size(), 20000u);
  const double sigma = options.range_noise_m;
  int within_3_sigma = 0;
  double max_distance = 0;
  for (const LidarPoint& p : points) {
    const Surface& s = world.surfaces[p.surface];
    const double distance = std::abs(s.Normal().dot(p.position.cast<double>()) - s.PlaneOffset());
    within_3_sigma += distance <= 3 * sigma;
    max_distance = std::max(max_distance, distance);
    EXPECT_GE(p.intensity, 0.0f);
    EXPECT_LE(p.intensity, 1.0f);
    const double range = (p.position.cast<double>() - sensor.translation).norm();
    EXPECT_LT(range, options.max_range_m + 6 * sigma);
  }
  std::printf("%zu points, %.3f%% within 3 sigma, max %.3f m\n", points.size(),
              100.0 * within_3_sigma / points.size(), max_distance);
  EXPECT_GT(within_3_sigma, 0.99 * points.size());
  EXPECT_LT(max_distance, 6 * sigma);
  // Without noise the points lie on the planes exactly.
  options.range_noise_m = 0;
  for (const LidarPoint& p : SimulateScan(world, sensor, options, 9)) {
    const Surface& s = world.surfaces[p.surface];
    ASSERT_NEAR(s.Normal().dot(p.position.cast<double>()), s.PlaneOffset(), 1e-4);
    ASSERT_TRUE(s.Contains(p.position.cast<double>(), 1e-4));
  }
}

TEST(Lidar, RenderedSurfacesMatchTheSampledOnes) {
  const World world = SmallWorld();
  LidarOptions options;
  const DrivePath path(world, DriveOptions::Survey(), world.options.length_m, 1);
  const std::vector<Rigid3d> sensors = {path.WorldFromSensorAtS(10.0, options.sensor_height_m),
                                        path.WorldFromSensorAtS(30.0, options.sensor_height_m)};
  const std::vector<LidarPoint> points = SimulateScans(world, sensors, options, 3);
  // A camera where the first scan was taken sees the points of both scans.
  const Camera camera = DriveOptions::Survey().camera;
  RenderOptions render;
  render.depth = true;
  render.surface_ids = true;
  const Rigid3d pose = path.CamFromWorld(path.TimeAtS(10.0));
  const RenderResult r = Renderer(camera, render).Render(world, pose);
  int seen = 0, same = 0;
  for (const LidarPoint& p : points) {
    const Eigen::Vector3d x = pose * p.position.cast<double>();
    if (x.z() < 1) continue;
    const Eigen::Vector2d pixel = camera.Project(x);
    const int u = static_cast<int>(std::lround(pixel.x())),
              v = static_cast<int>(std::lround(pixel.y()));
    if (u < 0 || v < 0 || u >= camera.width || v >= camera.height) continue;
    if (std::abs(r.depth.at<float>(v, u) - x.z()) > 0.1 + 0.02 * x.z()) continue;  // hidden
    ++seen;
    same += r.surface_id.at<int>(v, u) == p.surface;
  }
  std::printf("%d points seen by the camera, %.2f%% on the same surface\n", seen,
              100.0 * same / seen);
  EXPECT_GT(seen, 10000);
  EXPECT_GT(same, 0.97 * seen);
}

TEST(Lidar, ScansAreDeterministicAndIndependentOfThreads) {
  const World world = SmallWorld();
  LidarOptions options;
  options.azimuth_step_deg = 1.0;
  const DrivePath path(world, DriveOptions::Survey(), world.options.length_m, 1);
  std::vector<Rigid3d> sensors;
  for (double s = 0; s < 80; s += 20) sensors.push_back(path.WorldFromSensorAtS(s, 1.7));
  const std::vector<LidarPoint> a = SimulateScans(world, sensors, options, 5);
  options.num_threads = 1;
  const std::vector<LidarPoint> b = SimulateScans(world, sensors, options, 5);
  const std::vector<LidarPoint> c = SimulateScans(world, sensors, options, 6);
  ASSERT_EQ(a.size(), b.size());
  bool differs = a.size() != c.size();
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].position, b[i].position);
    ASSERT_EQ(a[i].scan, b[i].scan);
    if (i < c.size() && a[i].position != c[i].position) differs = true;
  }
  EXPECT_TRUE(differs);
  // Full circle: more points than the front half.
  options.azimuth_fov_deg = 360;
  EXPECT_GT(
      SimulateScan(world, sensors[1], options, 1).size(),
      1.5 * SimulateScan(world, sensors[1], LidarOptions{1.0, 1.7, 64, -25, 3, 1.0}, 1).size());
}

TEST(Lidar, PlyRoundTrip) {
  std::vector<LidarPoint> points(3);
  points[0].position = Eigen::Vector3f(1.5f, -2.25f, 3.0f);
  points[0].intensity = 0.25f;
  points[0].rgb = {1, 2, 3};
  points[2].position = Eigen::Vector3f(-100.125f, 7.5f, 0.0f);
  points[2].rgb = {255, 128, 0};
  const std::string path =
      (std::filesystem::temp_directory_path() / "epiloc_synth_ply_test.ply").string();
  WritePly(path, points);
  const std::vector<LidarPoint> back = ReadPly(path);
  ASSERT_EQ(back.size(), points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(back[i].position, points[i].position);
    EXPECT_EQ(back[i].intensity, points[i].intensity);
    EXPECT_EQ(back[i].rgb, points[i].rgb);
  }
  // A transform into another frame is applied on writing.
  WritePly(path, points, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)));
  EXPECT_FLOAT_EQ(ReadPly(path)[0].position.x(), 2.5f);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 5);
  EXPECT_THROW(ReadPly(path), Error);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace epiloc
