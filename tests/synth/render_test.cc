#include "epiloc/synth/render.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/synth/camera_presets.h"
#include "epiloc/synth/trajectory.h"

namespace epiloc {
namespace {

// One world for all tests of this file (each test runs in its own process under CTest).
const World& TestWorld() {
  static const World world = [] {
    WorldOptions o;
    o.length_m = 120;
    o.margin_after_m = 60;
    o.seed = 3;
    o.markers_per_facade = 2;
    o.marker_square_m = 0.3;
    return BuildWorld(o);
  }();
  return world;
}

Camera DistortedCamera(double k1, double k2) {
  Camera camera = DriveOptions::Query().camera;
  camera.distortion = {k1, k2, 0.0008, -0.0005, 0.0};
  return camera;
}

// Camera poses along the right lane (the survey's), every `step_m`.
std::vector<Rigid3d> LanePoses(const World& world, double step_m, double height_m = 1.6) {
  DriveOptions drive = DriveOptions::Survey();
  drive.camera_height_m = height_m;
  const DrivePath path(world, drive, world.options.length_m, 1);
  std::vector<Rigid3d> poses;
  for (double s = 5; s < world.options.length_m; s += step_m)
    poses.push_back(path.CamFromWorld(path.TimeAtS(s)));
  return poses;
}

struct CornerStats {
  int count = 0;
  double mean_px = 0.0;
  double max_px = 0.0;
  double max_x_fraction = 0.0;  // largest |x - cx| of a corner over the half width
};

// A camera 1.6 m above the road, 4-12 m before a marker, looking at it with the marker pushed
// towards a random part of the image by a random yaw and pitch (up to 0.45 and 0.2 rad times
// `spread`).
Rigid3d PoseFacing(const World& world, const Marker& m, Rng& rng, double spread = 1.0) {
  const RoadCoordinates rc = world.centreline.ToRoad(m.position_in_world.head<2>());
  const double d = rng.Uniform(-3.0, 3.0);
  const Eigen::Vector3d centre =
      world.RoadPoint(rc.s_m - rng.Uniform(4.0, 12.0), d) + Eigen::Vector3d(0, 0, 1.6);
  const Eigen::Vector3d to_marker = (m.position_in_world - centre).normalized();
  const double yaw =
      std::atan2(to_marker.y(), to_marker.x()) + rng.Uniform(-0.45 * spread, 0.45 * spread);
  const double pitch = std::asin(to_marker.z()) + rng.Uniform(-0.2 * spread, 0.2 * spread);
  const Eigen::Vector3d forward(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw),
                                std::sin(pitch));
  const Eigen::Vector3d right(std::sin(yaw), -std::cos(yaw), 0.0);
  Eigen::Matrix3d world_from_cam;
  world_from_cam << right, forward.cross(right), forward;
  return Rigid3d::FromMatrix(world_from_cam.transpose(), -world_from_cam.transpose() * centre);
}

// Detects the world's checkerboard markers with cv::cornerSubPix, starting 0.6 px off the
// projection, and compares with camera.Project(cam_from_world * X). Stops after `max_corners`;
// `spread` widens the poses' look-away angles (wide-angle cameras: corners out to the edges).
CornerStats MarkerErrors(const Camera& camera,
                         const RenderOptions& options,
                         int max_corners = 1 << 30,
                         double spread = 1.0) {
  const World& world = TestWorld();
  RenderOptions with_ids = options;
  with_ids.surface_ids = true;
  const Renderer renderer(camera, with_ids);
  CornerStats stats;
  double sum = 0;
  Rng rng(21);
  for (const Marker& m : world.markers) {
    if (stats.count >= max_corners) break;
    const Rigid3d pose = PoseFacing(world, m, rng, spread);
    {
      const Eigen::Vector3d x = pose * m.position_in_world;
      if (x.z() < 1.0) continue;
      const Eigen::Vector2d p = camera.Project(x);
      // Distance in pixels to the pattern's outer corners bounds the search window.
      const Surface& s = world.surfaces[m.surface];
      double reach = 1e9;
      for (const Eigen::Vector3d& d :
           {s.u_axis, s.v_axis, Eigen::Vector3d(-s.u_axis), Eigen::Vector3d(-s.v_axis)}) {
        const Eigen::Vector3d y = pose * (m.position_in_world + m.square_m * d);
        if (y.z() < 0.5)
          reach = 0;
        else
          reach = std::min(reach, (camera.Project(y) - p).norm());
      }
      if (reach < 7 || p.x() < 12 || p.y() < 12 || p.x() > camera.width - 13 ||
          p.y() > camera.height - 13)
        continue;
      const int win = std::min(6, static_cast<int>(0.7 * reach));
      const RenderResult r = renderer.Render(world, pose);
      cv::Mat grey;
      cv::cvtColor(r.image, grey, cv::COLOR_BGR2GRAY);
      // Visible: the whole window shows the marker's facade.
      bool visible = true;
      for (int dy = -win - 1; dy <= win + 1 && visible; ++dy) {
        for (int dx = -win - 1; dx <= win + 1 && visible; ++dx) {
          visible = r.surface_id.at<int>(static_cast<int>(std::lround(p.y())) + dy,
                                         static_cast<int>(std::lround(p.x())) + dx) == m.surface;
        }
      }
      if (!visible) continue;
      std::vector<cv::Point2f> corner = {cv::Point2f(p.x() + 0.6, p.y() - 0.6)};
      cv::cornerSubPix(
          grey, corner, cv::Size(win, win), cv::Size(-1, -1),
          cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
      const double error = std::hypot(corner[0].x - p.x(), corner[0].y - p.y());
      sum += error;
      stats.max_px = std::max(stats.max_px, error);
      stats.max_x_fraction =
          std::max(stats.max_x_fraction, std::abs(p.x() - camera.cx) / (0.5 * camera.width));
      ++stats.count;
    }
  }
  stats.mean_px = stats.count ? sum / stats.count : 0.0;
  return stats;
}

TEST(Render, MarkersAppearWhereTheCameraProjectsThem) {
  const CornerStats pinhole = MarkerErrors(DriveOptions::Survey().camera, RenderOptions());
  RecordProperty("pinhole_mean_px", std::to_string(pinhole.mean_px));
  std::printf("pinhole: %d corners, mean %.3f px, max %.3f px\n", pinhole.count, pinhole.mean_px,
              pinhole.max_px);
  EXPECT_GE(pinhole.count, 15);
  EXPECT_LT(pinhole.mean_px, 0.3);
  EXPECT_LT(pinhole.max_px, 0.5);
}

TEST(Render, MarkersAppearWhereTheDistortedCameraProjectsThem) {
  for (const double k1 : {-0.08, -0.25}) {
    const CornerStats distorted = MarkerErrors(DistortedCamera(k1, 0.3 * k1 * k1), RenderOptions());
    std::printf("k1 %.2f: %d corners, mean %.3f px, max %.3f px\n", k1, distorted.count,
                distorted.mean_px, distorted.max_px);
    EXPECT_GE(distorted.count, 15);
    EXPECT_LT(distorted.mean_px, 0.3);
    EXPECT_LT(distorted.max_px, 0.5);
  }
}

// The query variants' cameras (issue 14): the 1080p wide-angle dashcam (corners pushed out towards
// its distorted edges) and a strongly distorted VGA camera.
TEST(Render, MarkersAppearWhereTheDashcamAndAStronglyDistortedCameraProjectThem) {
  DriveOptions drive = DriveOptions::Query();
  ApplyQueryCameraPreset("dashcam1080", &drive);
  const Camera dashcam = drive.camera;
  ApplyQueryCameraPreset("vga", &drive);
  Camera strong = drive.camera;
  strong.distortion = {-0.35, 0.12, 0.001, -0.0008, 0.0};
  strong = WithHorizontalFovDeg(strong, 90.0);
  CheckDistortionInvertible(strong, "strong");
  for (const Camera& camera : {dashcam, strong}) {
    const CornerStats stats = MarkerErrors(camera, RenderOptions(), 12, 2.0);
    std::printf(
        "%dx%d, %.0f deg, k1 %.2f: %d corners out to %.0f %% of the half width, mean %.3f px, "
        "max %.3f px\n",
        camera.width, camera.height, HorizontalFovDeg(camera), camera.distortion[0], stats.count,
        100 * stats.max_x_fraction, stats.mean_px, stats.max_px);
    EXPECT_GE(stats.count, 12);
    EXPECT_GT(stats.max_x_fraction, 0.6);  // into the strongly distorted part
    EXPECT_LT(stats.mean_px, 0.3);
    EXPECT_LT(stats.max_px, 0.5);
  }
}

TEST(Render, SupersampledMarkersStayExact) {
  RenderOptions options;
  options.supersampling = 2;
  const CornerStats s = MarkerErrors(DistortedCamera(-0.1, 0.01), options);
  std::printf("supersampled: %d corners, mean %.3f px, max %.3f px\n", s.count, s.mean_px,
              s.max_px);
  EXPECT_GE(s.count, 15);
  EXPECT_LT(s.mean_px, 0.3);
  EXPECT_LT(s.max_px, 0.5);
}

// Depth at a sub-pixel position from the four neighbouring pixels (inverse depth is linear in the
// image over a plane), or NaN if they do not all show `surface`.
double DepthAt(const RenderResult& r, const Eigen::Vector2d& p, int surface) {
  const int x0 = static_cast<int>(std::floor(p.x())), y0 = static_cast<int>(std::floor(p.y()));
  const double fx = p.x() - x0, fy = p.y() - y0;
  double w = 0;
  for (int dy = 0; dy <= 1; ++dy) {
    for (int dx = 0; dx <= 1; ++dx) {
      if (r.surface_id.at<int>(y0 + dy, x0 + dx) != surface) return NAN;
      w += (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) / r.depth.at<float>(y0 + dy, x0 + dx);
    }
  }
  return 1.0 / w;
}

TEST(Render, DepthIsExactAndHiddenPointsAreBehind) {
  const World& world = TestWorld();
  for (const Camera& camera : {DriveOptions::Survey().camera, DistortedCamera(-0.08, 0.01)}) {
    RenderOptions options;
    options.depth = true;
    options.surface_ids = true;
    const Renderer renderer(camera, options);
    Rng rng(11);
    int checked = 0, occluded = 0;
    double max_error = 0;
    for (const Rigid3d& pose : LanePoses(world, 20.0)) {
      const RenderResult r = renderer.Render(world, pose);
      EXPECT_EQ(r.depth.type(), CV_32F);
      for (int trial = 0; trial < 3000; ++trial) {
        const int index = rng.UniformInt(0, world.surfaces.size() - 1);
        const Surface& s = world.surfaces[index];
        const std::array<Eigen::Vector3d, 4>& c = s.corners_in_world;
        const double a = rng.Uniform(), b = rng.Uniform();
        const Eigen::Vector3d x =
            (1 - b) * ((1 - a) * c[0] + a * c[1]) + b * ((1 - a) * c[3] + a * c[2]);
        const Eigen::Vector3d in_cam = pose * x;
        if (in_cam.z() < 0.5) continue;
        const Eigen::Vector2d p = camera.Project(in_cam);
        if (p.x() < 1 || p.y() < 1 || p.x() > camera.width - 2 || p.y() > camera.height - 2)
          continue;
        const double depth = DepthAt(r, p, index);
        if (std::isnan(depth)) continue;
        max_error = std::max(max_error, std::abs(depth - in_cam.z()));
        ++checked;
        // A point further along the same ray is hidden by this surface.
        if (s.kind == SurfaceKind::kFacade && occluded < 50) {
          const Eigen::Vector3d centre = pose.Inverse().translation;
          const Eigen::Vector3d behind = centre + 1.5 * (x - centre);
          const Eigen::Vector3d behind_cam = pose * behind;
          EXPECT_NEAR((camera.Project(behind_cam) - p).norm(), 0, 1e-6);
          EXPECT_LT(DepthAt(r, p, index), behind_cam.z() - 1.0);
          ++occluded;
        }
      }
    }
    std::printf("depth: %d points, max error %.2e m; %d occlusions\n", checked, max_error,
                occluded);
    EXPECT_GT(checked, 1000);
    EXPECT_GT(occluded, 20);
    EXPECT_LT(max_error, 0.01);
  }
}

TEST(Render, SurveyAndQueryFramesHaveManySiftFeatures) {
  const World& world = TestWorld();
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  for (const bool query : {false, true}) {
    const DriveOptions drive = query ? DriveOptions::Query() : DriveOptions::Survey();
    const DrivePath path(world, drive, world.options.length_m, 2);
    const Renderer renderer(drive.camera, drive.render);
    for (const double s : {15.0, 50.0, 85.0}) {
      const double t = path.TimeAtS(s);
      const RenderResult r = renderer.Render(world, path.CamFromWorld(t),
                                             path.CamFromWorld(t + 0.5 * drive.exposure_s), 1);
      cv::Mat grey;
      cv::cvtColor(r.image, grey, cv::COLOR_BGR2GRAY);
      std::vector<cv::KeyPoint> keypoints;
      sift->detect(grey, keypoints);
      std::printf("%s s=%.0f: %zu SIFT features\n", query ? "query" : "survey", s,
                  keypoints.size());
      EXPECT_GE(keypoints.size(), 300u) << (query ? "query" : "survey") << " at s = " << s;
    }
  }
}

TEST(Render, NoiseGainAndBlurBehave) {
  const World& world = TestWorld();
  const Camera camera = DriveOptions::Survey().camera;
  const Rigid3d pose = LanePoses(world, 50.0)[1];
  const RenderResult sharp = Renderer(camera, RenderOptions()).Render(world, pose);
  RenderOptions noisy;
  noisy.noise_sigma = 3.0;
  const Renderer noisy_renderer(camera, noisy);
  const cv::Mat a = noisy_renderer.Render(world, pose, std::nullopt, 1).image;
  const cv::Mat b = noisy_renderer.Render(world, pose, std::nullopt, 1).image;
  const cv::Mat c = noisy_renderer.Render(world, pose, std::nullopt, 2).image;
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0.0);
  cv::Mat diff;
  cv::subtract(a, sharp.image, diff, cv::noArray(), CV_32F);
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff.reshape(1), mean, stddev);
  EXPECT_NEAR(stddev[0], 3.0, 0.5);
  RenderOptions dark;
  dark.exposure_gain = 0.5;
  const cv::Mat d = Renderer(camera, dark).Render(world, pose).image;
  EXPECT_NEAR(cv::mean(d)[1], 0.5 * cv::mean(sharp.image)[1], 1.0);
  // Moving 0.5 m forward during the exposure blurs the edges of the image, not its centre.
  Rigid3d moved = pose;
  moved.translation.z() -= 0.5;
  const cv::Mat blurred = Renderer(camera, RenderOptions()).Render(world, pose, moved).image;
  const cv::Rect centre(camera.width / 2 - 10, camera.height / 2 - 10, 20, 20);
  const cv::Rect corner(0, camera.height - 60, 60, 60);
  EXPECT_LT(cv::norm(blurred(centre), sharp.image(centre), cv::NORM_L1) / 400, 4.0);
  EXPECT_GT(cv::norm(blurred(corner), sharp.image(corner), cv::NORM_L1) / 3600, 4.0);
}

TEST(Render, OptionsAreChecked) {
  RenderOptions o;
  o.supersampling = 0;
  EXPECT_THROW(o.Check(), Error);
  o = RenderOptions();
  o.noise_sigma = -1;
  EXPECT_THROW(Renderer(DriveOptions::Survey().camera, o), Error);
}

}  // namespace
}  // namespace epiloc
