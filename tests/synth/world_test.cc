#include "epiloc/synth/world.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/core/hash.h"

namespace epiloc {
namespace {

WorldOptions SmallWorld(uint64_t seed) {
  WorldOptions o;
  o.length_m = 80;
  o.margin_after_m = 40;
  o.seed = seed;
  return o;
}

std::string HashTextures(const World& world) {
  std::string all;
  for (const Texture& t : world.textures) {
    all += HashBytes(t.image.data, t.image.total() * t.image.elemSize());
  }
  return HashBytes(all.data(), all.size());
}

TEST(Centreline, ArcsAreContinuousAndRoadCoordinatesInvert) {
  CentrelinePiece a;
  a.s0_m = -10;
  a.length_m = 30;
  a.start_in_world = Eigen::Vector2d(-10, 0);
  CentrelinePiece b;
  b.s0_m = 20;
  b.length_m = 50;
  b.start_in_world = Eigen::Vector2d(20, 0);
  b.curvature_per_m = 1.0 / 40;
  Centreline line({a, b});
  EXPECT_NEAR((line.PointAt(0) - Eigen::Vector2d(0, 0)).norm(), 0, 1e-12);
  // A quarter circle of radius 40 to the left ends 40 m east and 40 m north of its start.
  CentrelinePiece quarter = b;
  quarter.length_m = 40 * M_PI / 2;
  Centreline turn({a, quarter});
  EXPECT_NEAR((turn.PointAt(20 + 40 * M_PI / 2) - Eigen::Vector2d(60, 40)).norm(), 0, 1e-9);
  EXPECT_NEAR(turn.YawAt(20 + 40 * M_PI / 2), M_PI / 2, 1e-12);
  Rng rng(5);
  for (int i = 0; i < 100; ++i) {
    const double s = rng.Uniform(-5, 65), d = rng.Uniform(-12, 12);
    const RoadCoordinates rc = line.ToRoad(line.PointAt(s, d));
    EXPECT_NEAR(rc.s_m, s, 1e-9);
    EXPECT_NEAR(rc.d_m, d, 1e-9);
  }
  CentrelinePiece gap = b;
  gap.start_in_world.x() += 1.0;
  EXPECT_THROW(Centreline({a, gap}), Error);
}

TEST(World, LayoutIsPlausible) {
  const World world = BuildWorld(SmallWorld(1));
  int counts[10] = {0};
  for (const Surface& s : world.surfaces) {
    ++counts[static_cast<int>(s.kind)];
    ASSERT_GE(s.texture, 0);
    const Texture& t = world.textures[s.texture];
    EXPECT_FALSE(t.levels.empty());
    // Corners coplanar with the texture frame.
    for (const Eigen::Vector3d& c : s.corners_in_world) {
      EXPECT_NEAR(s.Normal().dot(c), s.PlaneOffset(), 1e-9);
      EXPECT_TRUE(s.Contains(c, 1e-6));
    }
    EXPECT_TRUE(s.Contains(0.25 * (s.corners_in_world[0] + s.corners_in_world[1] +
                                   s.corners_in_world[2] + s.corners_in_world[3])));
  }
  for (const SurfaceKind kind :
       {SurfaceKind::kGround, SurfaceKind::kRoad, SurfaceKind::kSidewalk, SurfaceKind::kKerb,
        SurfaceKind::kFacade, SurfaceKind::kWall, SurfaceKind::kPole, SurfaceKind::kCar}) {
    EXPECT_GT(counts[static_cast<int>(kind)], 0) << SurfaceKindName(kind);
  }
  // Markers lie on their facades and never on the road side of the kerb.
  ASSERT_GT(world.markers.size(), 10u);
  for (const Marker& m : world.markers) {
    const Surface& s = world.surfaces[m.surface];
    EXPECT_EQ(s.kind, SurfaceKind::kFacade);
    EXPECT_TRUE(s.Contains(m.position_in_world));
    EXPECT_NEAR(s.Normal().dot(m.position_in_world), s.PlaneOffset(), 1e-9);
    const RoadCoordinates rc = world.centreline.ToRoad(m.position_in_world.head<2>());
    EXPECT_GT(std::abs(rc.d_m), world.options.road.asphalt_half_width_m() + 1.5);
  }
  // The road passes through the origin, s = 0.
  EXPECT_NEAR(world.RoadPoint(0, 0).norm(), 0, 1e-9);
}

TEST(World, DeterministicForASeed) {
  const World a = BuildWorld(SmallWorld(7));
  WorldOptions single = SmallWorld(7);
  single.num_threads = 1;
  const World b = BuildWorld(single);
  const World c = BuildWorld(SmallWorld(8));
  ASSERT_EQ(a.surfaces.size(), b.surfaces.size());
  for (size_t i = 0; i < a.surfaces.size(); ++i) {
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(a.surfaces[i].corners_in_world[k], b.surfaces[i].corners_in_world[k]);
    }
  }
  EXPECT_EQ(HashTextures(a), HashTextures(b));
  EXPECT_NE(HashTextures(a), HashTextures(c));
}

TEST(World, OptionsAreChecked) {
  WorldOptions o;
  o.length_m = -1;
  EXPECT_THROW(o.Check(), Error);
  o = WorldOptions();
  o.max_radius_m = 10;
  EXPECT_THROW(o.Check(), Error);
  o = WorldOptions();
  o.origin.lat_deg = 95;
  EXPECT_THROW(BuildWorld(o), Error);
}

}  // namespace
}  // namespace epiloc
