#include "epiloc/cloud/render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "epiloc/synth/lidar.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/trajectory.h"
#include "test_util.h"

namespace epiloc {
namespace {

Camera TestCamera() {
  Camera camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = 500.0;
  camera.fy = 510.0;
  camera.cx = 319.3;
  camera.cy = 241.7;
  return camera;
}

Rigid3d RandomPose(std::mt19937_64* rng) {
  std::normal_distribution<double> normal;
  const Eigen::Quaterniond rotation =
      Eigen::Quaterniond(normal(*rng), normal(*rng), normal(*rng), normal(*rng)).normalized();
  // Camera centres up to a kilometre from the origin, as in a large ENU frame.
  std::uniform_real_distribution<double> centre(-1000.0, 1000.0);
  const Eigen::Vector3d centre_in_world(centre(*rng), centre(*rng), 0.01 * centre(*rng));
  return Rigid3d(rotation, -(rotation * centre_in_world));
}

// The world point at depth z on the ray through pixel (u, v).
Eigen::Vector3d PointAtPixel(
    const Camera& camera, const Rigid3d& cam_from_world, double u, double v, double z) {
  const Eigen::Vector3d in_cam((u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z);
  return cam_from_world.Inverse() * in_cam;
}

PointCloud CloudOf(const std::vector<Eigen::Vector3d>& points_in_world) {
  PointCloud cloud;
  for (const Eigen::Vector3d& p : points_in_world) cloud.positions.push_back(p.cast<float>());
  return cloud;
}

CloudRenderOptions PointOptions() {
  CloudRenderOptions options;
  options.splat_size_m = 0.0;  // single pixels
  options.hole_fill_iterations = 0;
  return options;
}

bool Same(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  return cv::norm(a.reshape(1), b.reshape(1), cv::NORM_INF) == 0.0;
}

TEST(CloudRender, ASinglePointLandsOnItsRoundedPixelWithItsDepthAndIndex) {
  std::mt19937_64 rng(11);
  const Camera camera = TestCamera();
  std::uniform_real_distribution<double> pixel_u(-0.5, camera.width - 0.5);
  std::uniform_real_distribution<double> pixel_v(-0.5, camera.height - 0.5);
  std::uniform_real_distribution<double> depth(1.0, 100.0);
  int tested = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Rigid3d pose = RandomPose(&rng);
    const double u = pixel_u(rng), v = pixel_v(rng), z = depth(rng);
    // The float cloud moves the point by ~1e-4 m; skip rounding ties it could flip.
    if (std::abs(u - std::floor(u) - 0.5) < 0.01 || std::abs(v - std::floor(v) - 0.5) < 0.01) {
      continue;
    }
    // The point sits among others behind the camera, at a random index.
    std::vector<Eigen::Vector3d> points(5, PointAtPixel(camera, pose, u, v, -z));
    const int index = static_cast<int>(rng() % points.size());
    points[index] = PointAtPixel(camera, pose, u, v, z);
    const PointCloud cloud = CloudOf(points);
    const Eigen::Vector3d in_cam = pose * cloud.positions[index].cast<double>();
    const Eigen::Vector2d pixel = camera.Project(in_cam);
    const int x = static_cast<int>(std::lround(pixel.x())),
              y = static_cast<int>(std::lround(pixel.y()));
    const CloudRenderResult r = RenderCloud(cloud, camera, pose, PointOptions());
    ASSERT_EQ(r.points_drawn, 1) << "trial " << trial;
    ASSERT_EQ(cv::countNonZero(r.depth), 1);
    EXPECT_NEAR(r.depth.at<float>(y, x), in_cam.z(), 1e-5 * in_cam.z()) << "trial " << trial;
    EXPECT_EQ(r.point_index.at<int>(y, x), index);
    EXPECT_EQ(cv::countNonZero(r.point_index >= 0), 1);
    EXPECT_EQ(r.depth.type(), CV_32F);
    EXPECT_EQ(r.point_index.type(), CV_32S);
    EXPECT_EQ(r.shading, RenderShading::kDepth);
    ASSERT_EQ(r.image.type(), CV_8UC1);
    EXPECT_GT(r.image.at<uint8_t>(y, x), 0);
    // With splats and hole filling the point still owns its pixel.
    const CloudRenderResult splat = RenderCloud(cloud, camera, pose);
    EXPECT_EQ(splat.point_index.at<int>(y, x), index);
    EXPECT_EQ(splat.depth.at<float>(y, x), r.depth.at<float>(y, x));
    ++tested;
  }
  EXPECT_GT(tested, 30);
}

TEST(CloudRender, TheNearerOfTwoPointsOnARayWinsInAnyOrderAndThreadCount) {
  std::mt19937_64 rng(12);
  const Camera camera = TestCamera();
  for (int trial = 0; trial < 10; ++trial) {
    const Rigid3d pose = RandomPose(&rng);
    const int u = 100 + static_cast<int>(rng() % 400), v = 50 + static_cast<int>(rng() % 300);
    const Eigen::Vector3d near_point = PointAtPixel(camera, pose, u, v, 7.0);
    const Eigen::Vector3d far_point = PointAtPixel(camera, pose, u, v, 9.0);
    for (const int threads : {1, 2}) {
      CloudRenderOptions options = PointOptions();
      options.num_threads = threads;
      const CloudRenderResult a =
          RenderCloud(CloudOf({near_point, far_point}), camera, pose, options);
      const CloudRenderResult b =
          RenderCloud(CloudOf({far_point, near_point}), camera, pose, options);
      EXPECT_NEAR(a.depth.at<float>(v, u), 7.0f, 1e-4);
      EXPECT_NEAR(b.depth.at<float>(v, u), 7.0f, 1e-4);
      EXPECT_EQ(a.point_index.at<int>(v, u), 0);
      EXPECT_EQ(b.point_index.at<int>(v, u), 1);
      EXPECT_EQ(a.points_drawn, 2);
      // Equal depths: the lower index wins.
      const CloudRenderResult c =
          RenderCloud(CloudOf({far_point, far_point}), camera, pose, options);
      EXPECT_EQ(c.point_index.at<int>(v, u), 0);
    }
  }
}

TEST(CloudRender, CullsPointsBehindTooNearTooFarAndOutsideTheImage) {
  const Camera camera = TestCamera();
  const Rigid3d pose;  // camera at the origin looking along world z
  CloudRenderOptions options = PointOptions();
  options.near_m = 1.0;
  options.far_m = 50.0;
  const double cx = camera.cx, cy = camera.cy, w = camera.width, h = camera.height;
  auto at = [&](double u, double v, double z) { return PointAtPixel(camera, pose, u, v, z); };
  const std::vector<Eigen::Vector3d> culled = {
      {0, 0, -5},             // behind
      at(cx, cy, 0.9),        // nearer than near_m
      at(cx, cy, 50.5),       // beyond far_m
      at(-0.6, cy, 20),       // left of the image
      at(w - 0.4, cy, 20),    // right of it
      at(cx, -0.6, 20),       // above
      at(cx, h - 0.4, 20),    // below
      {std::nan(""), 0, 10},  // not a number
  };
  const CloudRenderResult r = RenderCloud(CloudOf(culled), camera, pose, options);
  EXPECT_EQ(r.points_drawn, 0);
  EXPECT_EQ(cv::countNonZero(r.depth), 0);
  EXPECT_EQ(cv::countNonZero(r.point_index >= 0), 0);
  // Just inside each border and range limit: drawn.
  const std::vector<Eigen::Vector3d> kept = {
      at(cx, cy, 1.01),    at(cx, cy, 49.9), at(-0.4, cy, 20),
      at(w - 0.6, cy, 20), at(cx, -0.4, 20), at(cx, h - 0.6, 20),
  };
  const CloudRenderResult k = RenderCloud(CloudOf(kept), camera, pose, options);
  EXPECT_EQ(k.points_drawn, 6);
  EXPECT_EQ(k.point_index.at<int>(242, 0), 2);
  EXPECT_EQ(k.point_index.at<int>(242, camera.width - 1), 3);
  EXPECT_EQ(k.point_index.at<int>(0, 319), 4);
  EXPECT_EQ(k.point_index.at<int>(camera.height - 1, 319), 5);
}

TEST(CloudRender, SplatSideGrowsAsDepthShrinksPerTheRule) {
  const Camera camera = TestCamera();
  const Rigid3d pose;
  CloudRenderOptions options;
  options.splat_size_m = 0.1;
  options.max_splat_px = 9;
  options.hole_fill_iterations = 0;
  const int u = 300, v = 200;
  int previous_side = 0;
  // splat_size_m * fx / z = 50 / z, away from rounding ties.
  for (const double z : {80.0, 60.0, 30.0, 17.0, 13.0, 11.0, 9.0, 7.5, 6.5, 6.0, 5.0, 2.0}) {
    const CloudRenderResult r =
        RenderCloud(CloudOf({PointAtPixel(camera, pose, u, v, z)}), camera, pose, options);
    // The odd side nearest to 50 / z: 1 beyond z = 25 m, 3 beyond 12.5, 5 beyond 8.33, 7 beyond
    // 6.25, else 9.
    const double size = options.splat_size_m * camera.fx / z;
    const int side = size >= 9 ? 9 : size < 2 ? 1 : size < 4 ? 3 : size < 6 ? 5 : size < 8 ? 7 : 9;
    const cv::Rect expected(u - side / 2, v - side / 2, side, side);
    EXPECT_EQ(cv::boundingRect(r.depth > 0), expected) << "z " << z;
    EXPECT_EQ(cv::countNonZero(r.depth), side * side) << "z " << z;
    EXPECT_EQ(cv::countNonZero(r.point_index == 0), side * side);
    EXPECT_GE(side, previous_side);
    previous_side = side;
  }
  EXPECT_EQ(previous_side, options.max_splat_px);
}

TEST(CloudRender, LiftPixelReturnsThePointAtItsSplatCentre) {
  std::mt19937_64 rng(15);
  const Camera camera = TestCamera();
  std::uniform_real_distribution<double> depth(2.0, 100.0);
  for (int trial = 0; trial < 5; ++trial) {
    const Rigid3d pose = RandomPose(&rng);
    std::vector<Eigen::Vector3d> points;
    std::vector<Eigen::Vector2i> pixels;
    for (int v = 10; v < camera.height; v += 20) {
      for (int u = 10; u < camera.width; u += 20) {
        points.push_back(PointAtPixel(camera, pose, u, v, depth(rng)));
        pixels.emplace_back(u, v);
      }
    }
    const PointCloud cloud = CloudOf(points);
    const CloudRenderResult r = RenderCloud(cloud, camera, pose);
    for (size_t i = 0; i < points.size(); ++i) {
      Eigen::Vector3d lifted;
      ASSERT_TRUE(LiftPixel(r, camera, pose, pixels[i].x(), pixels[i].y(), &lifted));
      const Eigen::Vector3d expected = cloud.positions[i].cast<double>();
      const double range = (pose * expected).norm();
      ASSERT_LT((lifted - expected).norm(), 1e-6 * range + 1e-4) << "point " << i;
    }
    // A sub-pixel position lifts along its own ray at the pixel's depth.
    Eigen::Vector3d lifted;
    ASSERT_TRUE(LiftPixel(r, camera, pose, 10.3, 9.8, &lifted));
    const Eigen::Vector3d in_cam = pose * lifted;
    EXPECT_NEAR(in_cam.z(), r.depth.at<float>(10, 10), 1e-4 * in_cam.z());
    EXPECT_NEAR(camera.Project(in_cam).x(), 10.3, 1e-6);
    EXPECT_NEAR(camera.Project(in_cam).y(), 9.8, 1e-6);
    EXPECT_FALSE(LiftPixel(r, camera, pose, 0, 0, &lifted));      // empty
    EXPECT_FALSE(LiftPixel(r, camera, pose, -0.6, 10, &lifted));  // outside
    EXPECT_FALSE(LiftPixel(r, camera, pose, 10, camera.height - 0.4, &lifted));
  }
}

// Points on random planes with intensity and colour, plus scattered points.
PointCloud RandomScene(uint64_t seed, int n) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    const float a = unit(rng), b = unit(rng);
    Eigen::Vector3f p;
    switch (i % 3) {
      case 0:
        p = {40 * a - 20, 1.6f, 40 * b};
        break;  // ground (camera y down)
      case 1:
        p = {-6.0f, 10 * a - 8.4f, 40 * b};
        break;  // a wall on the left
      default:
        p = {30 * a - 15, 12 * b - 10, 5 + 40 * unit(rng)};
        break;
    }
    cloud.positions.push_back(p);
    cloud.intensity.push_back(unit(rng));
    cloud.rgb.push_back({static_cast<uint8_t>(rng() % 256), static_cast<uint8_t>(rng() % 256),
                         static_cast<uint8_t>(rng() % 256)});
  }
  return cloud;
}

TEST(CloudRender, ResultsAreIdenticalForAnyThreadCount) {
  const PointCloud cloud = RandomScene(16, 200000);
  const Camera camera = TestCamera();
  const Rigid3d pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY())),
                     Eigen::Vector3d(0.2, -0.1, 0.3));
  for (const RenderShading shading :
       {RenderShading::kIntensity, RenderShading::kColour, RenderShading::kDepth}) {
    CloudRenderOptions options;
    options.shading = shading;
    options.num_threads = 1;
    const CloudRenderResult a = RenderCloud(cloud, camera, pose, options);
    EXPECT_GT(a.pixels_filled, 0);
    EXPECT_GT(cv::countNonZero(a.point_index >= 0), camera.width * camera.height / 4);
    for (const int threads : {2, 3, 7}) {
      options.num_threads = threads;
      const CloudRenderResult b = RenderCloud(cloud, camera, pose, options);
      EXPECT_TRUE(Same(a.image, b.image)) << RenderShadingName(shading) << threads;
      EXPECT_TRUE(Same(a.depth, b.depth));
      EXPECT_TRUE(Same(a.point_index, b.point_index));
      EXPECT_EQ(a.points_drawn, b.points_drawn);
      EXPECT_EQ(a.pixels_filled, b.pixels_filled);
    }
  }
}

// A near grid of points in front of a far wall: the splats leave gaps through which the wall
// shows, and there are holes in the grid.
TEST(CloudRender, HoleFillingCoversGapsAndHidesSeeThroughButKeepsSilhouettes) {
  const Camera camera = TestCamera();
  const Rigid3d pose;
  std::vector<Eigen::Vector3d> points;
  // Near square patch at z = 10 m: points every 4 pixels, splats of 2 pixels.
  for (int v = 200; v <= 280; v += 4) {
    for (int u = 280; u <= 360; u += 4) points.push_back(PointAtPixel(camera, pose, u, v, 10));
  }
  const size_t num_near = points.size();
  // Far wall at 40 m behind it, dense (every pixel).
  for (int v = 150; v <= 330; ++v) {
    for (int u = 230; u <= 410; ++u) points.push_back(PointAtPixel(camera, pose, u, v, 40));
  }
  CloudRenderOptions options;
  options.splat_size_m = 0.04;  // 2 px at 10 m, 1 px at 40 m
  options.hole_fill_iterations = 0;
  const PointCloud cloud = CloudOf(points);
  const CloudRenderResult raw = RenderCloud(cloud, camera, pose, options);
  options.hole_fill_iterations = 2;
  const CloudRenderResult filled = RenderCloud(cloud, camera, pose, options);
  EXPECT_EQ(raw.pixels_filled, 0);
  EXPECT_GT(filled.pixels_filled, 0);
  int see_through_raw = 0, see_through_filled = 0;
  for (int v = 202; v < 280; ++v) {
    for (int u = 282; u < 360; ++u) {
      see_through_raw += raw.depth.at<float>(v, u) > 20;
      see_through_filled += filled.depth.at<float>(v, u) > 20;
      if (filled.point_index.at<int>(v, u) < 0) {
        EXPECT_NEAR(filled.depth.at<float>(v, u), 10.0f, 1e-3) << u << "," << v;
      }
    }
  }
  EXPECT_GT(see_through_raw, 1000);
  EXPECT_EQ(see_through_filled, 0);
  // The wall around the patch is untouched: the silhouette does not grow.
  for (int v = 150; v <= 330; ++v) {
    for (int u = 230; u <= 410; ++u) {
      if (u >= 279 && u <= 361 && v >= 199 && v <= 281) continue;
      ASSERT_EQ(filled.depth.at<float>(v, u), 40.0f) << u << "," << v;
      ASSERT_GE(filled.point_index.at<int>(v, u), static_cast<int>(num_near));
    }
  }
  // Outside the wall nothing is filled.
  EXPECT_EQ(cv::countNonZero(filled.depth(cv::Rect(0, 0, 229, camera.height))), 0);
}

World SmallWorld() {
  WorldOptions o;
  o.length_m = 80;
  o.margin_after_m = 60;
  o.seed = 4;
  return BuildWorld(o);
}

TEST(CloudRender, LidarRenderingAgreesWithTheExactDepthOfTheSyntheticWorld) {
  const World world = SmallWorld();
  const DriveOptions drive = DriveOptions::Survey();
  const DrivePath path(world, drive, world.options.length_m, 1);
  LidarOptions lidar;
  std::vector<Rigid3d> sensors;
  for (double s = 0; s <= 60; s += lidar.scan_spacing_m) {
    sensors.push_back(path.WorldFromSensorAtS(s, lidar.sensor_height_m));
  }
  PointCloud cloud;
  for (const LidarPoint& p : SimulateScans(world, sensors, lidar, 3)) {
    cloud.positions.push_back(p.position);
    cloud.intensity.push_back(p.intensity);
  }
  const Camera& camera = drive.camera;
  ASSERT_FALSE(camera.HasDistortion());
  RenderOptions exact_options;
  exact_options.depth = true;
  const Renderer exact(camera, exact_options);
  for (const double s : {15.0, 34.0}) {
    const Rigid3d pose = path.CamFromWorld(path.TimeAtS(s));
    const RenderResult truth = exact.Render(world, pose);
    const CloudRenderResult r = RenderCloud(cloud, camera, pose);
    std::vector<double> drawn, filled;
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) {
        const float z = r.depth.at<float>(v, u), z_true = truth.depth.at<float>(v, u);
        if (z <= 0 || z_true <= 0) continue;
        (r.point_index.at<int>(v, u) >= 0 ? drawn : filled)
            .push_back(std::abs(z - z_true) / z_true);
      }
    }
    auto median = [](std::vector<double> x) {
      std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
      return x[x.size() / 2];
    };
    const double within_5 =
        std::count_if(drawn.begin(), drawn.end(), [](double d) { return d < 0.05; }) /
        static_cast<double>(drawn.size());
    std::printf(
        "s=%.0f m: %zu points drawn, %zu pixels drawn (median rel. depth difference "
        "%.3f%%, %.1f%% within 5%%), %zu filled (median %.3f%%)\n",
        s, static_cast<size_t>(r.points_drawn), drawn.size(), 100 * median(drawn), 100 * within_5,
        filled.size(), filled.empty() ? 0.0 : 100 * median(filled));
    ASSERT_GT(drawn.size(), camera.width * camera.height / 4);
    EXPECT_LT(median(drawn), 0.02);
    EXPECT_GT(within_5, 0.85);
    ASSERT_FALSE(filled.empty());
    EXPECT_LT(median(filled), 0.05);
  }
}

TEST(CloudRender, RejectsInvalidOptionsAndMissingAttributes) {
  const Camera camera = TestCamera();
  const PointCloud cloud = CloudOf({{0, 0, 5}});
  auto expect_option_error = [&](auto modify, const std::string& field) {
    CloudRenderOptions options;
    modify(options);
    ExpectError([&] { options.Check(); }, {"cloud render options", field});
    ExpectError([&] { RenderCloud(cloud, camera, Rigid3d(), options); }, {field});
  };
  expect_option_error([](CloudRenderOptions& o) { o.near_m = 0; }, "near_m");
  expect_option_error([](CloudRenderOptions& o) { o.far_m = 0.4; }, "far_m");
  expect_option_error([](CloudRenderOptions& o) { o.far_m = INFINITY; }, "far_m");
  expect_option_error([](CloudRenderOptions& o) { o.splat_size_m = -1; }, "splat_size_m");
  expect_option_error([](CloudRenderOptions& o) { o.max_splat_px = 0; }, "max_splat_px");
  expect_option_error([](CloudRenderOptions& o) { o.max_splat_px = 65; }, "max_splat_px");
  expect_option_error([](CloudRenderOptions& o) { o.hole_fill_iterations = -1; },
                      "hole_fill_iterations");
  expect_option_error([](CloudRenderOptions& o) { o.hole_fill_radius_px = 0; },
                      "hole_fill_radius_px");
  expect_option_error([](CloudRenderOptions& o) { o.see_through_ratio = 0; }, "see_through_ratio");
  expect_option_error([](CloudRenderOptions& o) { o.num_threads = 0; }, "num_threads");
  expect_option_error([](CloudRenderOptions& o) { o.shading = static_cast<RenderShading>(9); },
                      "shading");

  CloudRenderOptions options;
  options.shading = RenderShading::kColour;
  ExpectError([&] { RenderCloud(cloud, camera, Rigid3d(), options); },
              {"shading 'colour' needs a cloud with colour"});
  options.shading = RenderShading::kIntensity;
  ExpectError([&] { RenderCloud(cloud, camera, Rigid3d(), options); },
              {"shading 'intensity' needs a cloud with intensity"});
  PointCloud bad = cloud;
  bad.intensity = {0.5f, 0.5f};
  ExpectError([&] { RenderCloud(bad, camera, Rigid3d()); }, {"2 intensities for 1 points"});
  bad = cloud;
  bad.rgb.resize(3);
  ExpectError([&] { RenderCloud(bad, camera, Rigid3d()); }, {"3 colours for 1 points"});
  Camera no_focal = camera;
  no_focal.fx = 0;
  ExpectError([&] { RenderCloud(cloud, no_focal, Rigid3d()); }, {"cloud render: camera"});

  // kAuto picks what the cloud has.
  PointCloud coloured = cloud;
  coloured.rgb = {{10, 20, 30}};
  const CloudRenderResult r = RenderCloud(coloured, camera, Rigid3d());
  EXPECT_EQ(r.shading, RenderShading::kColour);
  ASSERT_EQ(r.image.type(), CV_8UC3);
  const int u = static_cast<int>(std::lround(camera.cx)),
            v = static_cast<int>(std::lround(camera.cy));
  EXPECT_EQ(r.image.at<cv::Vec3b>(v, u), cv::Vec3b(30, 20, 10));  // BGR

  // LiftPixel and ColouriseDepth check their inputs.
  Eigen::Vector3d lifted;
  Camera other = camera;
  other.width = 100;
  ExpectError([&] { LiftPixel(r, other, Rigid3d(), 1, 1, &lifted); }, {"lift pixel"});
  ExpectError([&] { LiftPixel(CloudRenderResult(), camera, Rigid3d(), 1, 1, &lifted); },
              {"lift pixel"});
  ExpectError([&] { ColouriseDepth(r.point_index); }, {"CV_32F"});
  ExpectError([&] { ColouriseDepth(r.depth, 5, 1); }, {"near_m < far_m"});
  const cv::Mat picture = ColouriseDepth(r.depth);
  EXPECT_EQ(picture.type(), CV_8UC3);
  EXPECT_GT(cv::countNonZero(picture.reshape(1)), 0);
  EXPECT_EQ(picture.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));
}

}  // namespace
}  // namespace epiloc
