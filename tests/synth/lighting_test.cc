#include "epiloc/synth/lighting.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/synth/cars.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/trajectory.h"

namespace epiloc {
namespace {

const World& TestWorld() {
  static const World world = [] {
    WorldOptions o;
    o.length_m = 60;
    o.margin_after_m = 30;
    o.seed = 3;
    o.vegetation.fraction = 0.5;  // trees and hedges cast shadows too
    return BuildWorld(o);
  }();
  return world;
}

// Brute force, independent of Lighting's caster grid: does the ray from p towards the sun meet
// any surface but `own` (world surfaces first, then `extra`)?
bool RayBlocked(const World& world,
                const std::vector<Surface>& extra,
                const Eigen::Vector3d& p,
                int own,
                const Eigen::Vector3d& sun) {
  const int n = static_cast<int>(world.surfaces.size());
  for (int i = 0; i < n + static_cast<int>(extra.size()); ++i) {
    const Surface& s = i < n ? world.surfaces[i] : extra[i - n];
    if (i == own || s.texture < 0) continue;
    const double denom = s.Normal().dot(sun);
    if (std::abs(denom) < 1e-12) continue;
    const double t = (s.PlaneOffset() - s.Normal().dot(p)) / denom;
    if (t > 1e-6 && s.Contains(p + t * sun)) return true;
  }
  return false;
}

// A survey camera on the right lane at distance s.
Rigid3d PoseAt(const World& world, double s_m) {
  const DrivePath path(world, DriveOptions::Survey(), world.options.length_m, 1);
  return path.CamFromWorld(path.TimeAtS(s_m));
}

struct ShadowCount {
  int lit = 0, shadowed = 0, checked = 0, wrong = 0;
  int by_extra = 0;  // shadowed by the extra surfaces alone
  std::vector<int> shadowed_pixels;
};

// Compares a sunlit rendering with the unshaded one at random pixels of horizontal ground (road,
// pavement): each must be darkened by exactly the model's factor for the analytic shadow decision
// at the pixel centre's surface point.
ShadowCount CheckShading(const World& world,
                         const std::vector<Surface>& extra,
                         const std::vector<Texture>& extra_textures,
                         const Rigid3d& pose,
                         const SunOptions& sun,
                         uint64_t seed) {
  const Camera camera = DriveOptions::Survey().camera;
  RenderOptions options;
  options.depth = true;
  options.surface_ids = true;
  const Renderer renderer(camera, options);
  RenderExtras plain;
  plain.surfaces = &extra;
  plain.textures = &extra_textures;
  const RenderResult unshaded = renderer.Render(world, pose, std::nullopt, std::nullopt, plain);
  const Lighting lighting(world, sun);
  RenderExtras lit = plain;
  lit.lighting = &lighting;
  const RenderResult shaded = renderer.Render(world, pose, std::nullopt, std::nullopt, lit);
  EXPECT_EQ(cv::norm(unshaded.surface_id, shaded.surface_id, cv::NORM_INF), 0.0);

  const Eigen::Vector3d direction = sun.DirectionInWorld();
  const Rigid3d world_from_cam = pose.Inverse();
  const int n = static_cast<int>(world.surfaces.size());
  ShadowCount count;
  Rng rng(seed);
  for (int trial = 0; trial < 4000; ++trial) {
    const int x = rng.UniformInt(0, camera.width - 1), y = rng.UniformInt(0, camera.height - 1);
    const int id = shaded.surface_id.at<int>(y, x);
    if (id < 0) continue;
    const Surface& s = id < n ? world.surfaces[id] : extra[id - n];
    if (s.kind != SurfaceKind::kRoad && s.kind != SurfaceKind::kSidewalk) continue;
    const double z = shaded.depth.at<float>(y, x);
    // The pixel centre's surface point, exactly (the stored depth is only a float).
    const Eigen::Vector3d ray =
        world_from_cam.rotation *
        Eigen::Vector3d((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1);
    const Eigen::Vector3d centre = world_from_cam.translation;
    const double t = (s.PlaneOffset() - s.Normal().dot(centre)) / s.Normal().dot(ray);
    EXPECT_NEAR(t, z, 1e-3 * z);
    const Eigen::Vector3d p = centre + t * ray;
    const bool blocked = RayBlocked(world, extra, p, id, direction);
    if (blocked && !RayBlocked(world, {}, p, id, direction)) ++count.by_extra;
    // Horizontal ground seen from above: cos(incidence) = sin(elevation).
    const double factor = sun.ambient + (blocked ? 0.0 : sun.direct * direction.z());
    const cv::Vec3b a = unshaded.image.at<cv::Vec3b>(y, x), b = shaded.image.at<cv::Vec3b>(y, x);
    double error = 0;
    for (int c = 0; c < 3; ++c) {
      if (a[c] * factor < 254) error = std::max(error, std::abs(b[c] - factor * a[c]));
    }
    ++count.checked;
    // 8-bit rounding of both images: at most 0.5 + 0.5 * factor.
    if (error > 0.5 + 0.5 * factor + 1e-9) ++count.wrong;
    (blocked ? count.shadowed : count.lit)++;
    if (blocked) count.shadowed_pixels.push_back(y * camera.width + x);
  }
  return count;
}

TEST(Lighting, ShadowsFollowTheSunExactly) {
  const World& world = TestWorld();
  // Sun from the left of the road, then from the right: the buildings' shadows fall on the
  // road from opposite sides.
  const Rigid3d pose = PoseAt(world, 20.0);
  const Eigen::Vector3d forward = pose.Inverse().rotation * Eigen::Vector3d::UnitZ();
  const double road_azimuth_deg = std::atan2(forward.x(), forward.y()) * 180 / M_PI;
  std::vector<std::vector<int>> shadowed;
  for (const double side : {-90.0, 90.0}) {
    SunOptions sun;
    sun.azimuth_deg = road_azimuth_deg + side + 20;
    sun.elevation_deg = 55;
    const ShadowCount count = CheckShading(world, {}, {}, pose, sun, 7);
    std::printf("sun azimuth %.0f: %d ground pixels, %d lit, %d in shadow, %d wrong\n",
                sun.azimuth_deg, count.checked, count.lit, count.shadowed, count.wrong);
    EXPECT_GT(count.lit, 100);
    EXPECT_GT(count.shadowed, 100);
    // Only pixels whose centre lies within float precision of a shadow edge may differ.
    EXPECT_LE(count.wrong, count.checked / 500);
    shadowed.push_back(count.shadowed_pixels);
  }
  // The same random pixels: the shadows moved.
  int moved = 0;
  for (const int p : shadowed[0]) {
    moved += std::find(shadowed[1].begin(), shadowed[1].end(), p) == shadowed[1].end();
  }
  EXPECT_GT(moved, 100);
}

TEST(Lighting, MovingCarsCastShadowsToo) {
  const World& world = TestWorld();
  const Rigid3d pose = PoseAt(world, 20.0);
  // A car 9 m ahead in the lane, the sun low in front: its shadow falls on the road towards the
  // camera (and the buildings' shadows mostly along the road, not across it).
  const CarModel car = MakeCarModel(5);
  const Eigen::Vector3d ahead = world.RoadPoint(29.0, world.RightLaneCentre());
  const Rigid3d world_from_body(
      Eigen::Quaterniond(Eigen::AngleAxisd(world.centreline.YawAt(29.0), Eigen::Vector3d::UnitZ())),
      ahead);
  std::vector<Surface> extra;
  PlaceCar(car, world_from_body, 0, &extra);
  const Eigen::Vector3d forward = pose.Inverse().rotation * Eigen::Vector3d::UnitZ();
  SunOptions sun;
  sun.azimuth_deg = std::atan2(forward.x(), forward.y()) * 180 / M_PI + 15;
  sun.elevation_deg = 30;
  const ShadowCount count = CheckShading(world, extra, car.textures, pose, sun, 9);
  std::printf("car: %d ground pixels, %d in shadow (%d of the car's), %d wrong\n", count.checked,
              count.shadowed, count.by_extra, count.wrong);
  EXPECT_LE(count.wrong, count.checked / 500);
  EXPECT_GT(count.by_extra, 20);
  // Under the car, the road is in the car's shadow (and not in the world's).
  const Lighting lighting(world, sun);
  const Eigen::Vector3d under = world.RoadPoint(29.0, world.RightLaneCentre());
  EXPECT_TRUE(lighting.InShadow(under, -1, &extra));
  EXPECT_FALSE(lighting.InShadow(under, -1));
}

TEST(Lighting, ExposureAndWhiteBalanceScaleTheChannels) {
  const World& world = TestWorld();
  const Camera camera = DriveOptions::Survey().camera;
  const Rigid3d pose = PoseAt(world, 30.0);
  const cv::Mat plain = Renderer(camera, RenderOptions()).Render(world, pose).image;
  RenderOptions options;
  options.exposure_gain = 1.2;
  options.white_balance_rgb = {1.1, 1.0, 0.7};
  const cv::Mat changed = Renderer(camera, options).Render(world, pose).image;
  const double gain_bgr[3] = {1.2 * 0.7, 1.2 * 1.0, 1.2 * 1.1};
  double max_error = 0;
  int checked = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const cv::Vec3b a = plain.at<cv::Vec3b>(y, x), b = changed.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        if (a[c] * gain_bgr[c] > 254) continue;  // saturated
        max_error = std::max(max_error, std::abs(b[c] - gain_bgr[c] * a[c]));
        ++checked;
      }
    }
  }
  std::printf("exposure and white balance: %d channel values, max error %.2f levels\n", checked,
              max_error);
  EXPECT_GT(checked, camera.width * camera.height);
  EXPECT_LE(max_error, 0.5 + 0.5 * 1.32 + 1e-9);  // rounding of both images
  RenderOptions bad;
  bad.white_balance_rgb = {1.0, 0.0, 1.0};
  EXPECT_THROW(bad.Check(), Error);
}

TEST(Lighting, OptionsAreChecked) {
  SunOptions sun;
  sun.elevation_deg = 5;
  EXPECT_THROW(sun.Check(), Error);
  sun = SunOptions();
  sun.ambient = -0.1;
  EXPECT_THROW(Lighting(TestWorld(), sun), Error);
  // North at 0 deg, east at 90 deg, clockwise.
  sun = SunOptions();
  sun.azimuth_deg = 90;
  sun.elevation_deg = 90;
  EXPECT_NEAR((sun.DirectionInWorld() - Eigen::Vector3d::UnitZ()).norm(), 0, 1e-12);
  sun.elevation_deg = 30;
  EXPECT_NEAR(sun.DirectionInWorld().x(), std::cos(30 * M_PI / 180), 1e-12);
  EXPECT_NEAR(sun.DirectionInWorld().y(), 0, 1e-12);
  // A lighting built for another world is refused.
  WorldOptions small;
  small.length_m = 30;
  small.margin_after_m = 10;
  const World other = BuildWorld(small);
  const Lighting lighting(other, SunOptions());
  RenderExtras extras;
  extras.lighting = &lighting;
  EXPECT_THROW(
      Renderer(DriveOptions::Survey().camera, RenderOptions())
          .Render(TestWorld(), PoseAt(TestWorld(), 10), std::nullopt, std::nullopt, extras),
      Error);
}

}  // namespace
}  // namespace epiloc
