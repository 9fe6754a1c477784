// Vegetation of the synthetic world (WorldOptions::vegetation).
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/synth/lighting.h"
#include "epiloc/synth/world.h"

namespace epiloc {
namespace {

WorldOptions Options(double fraction) {
  WorldOptions o;
  o.length_m = 60;
  o.margin_after_m = 30;
  o.seed = 6;
  o.vegetation.fraction = fraction;
  return o;
}

const World& GreenWorld() {
  static const World world = BuildWorld(Options(0.5));
  return world;
}

const World& PlainWorld() {
  static const World world = BuildWorld(Options(0.0));
  return world;
}

Eigen::Vector3d Centre(const Surface& s) {
  return 0.25 * (s.corners_in_world[0] + s.corners_in_world[1] + s.corners_in_world[2] +
                 s.corners_in_world[3]);
}

TEST(Vegetation, CoversTheRequestedShareAndLeavesTheRestOfTheWorldAlone) {
  const World& plain = PlainWorld();
  const World& green = GreenWorld();
  EXPECT_TRUE(plain.vegetation.empty());
  // The world without vegetation is the first part of the world with it, unchanged.
  ASSERT_GT(green.surfaces.size(), plain.surfaces.size());
  for (size_t i = 0; i < plain.surfaces.size(); ++i) {
    EXPECT_EQ(green.surfaces[i].corners_in_world[0], plain.surfaces[i].corners_in_world[0]);
    EXPECT_EQ(green.surfaces[i].texture, plain.surfaces[i].texture);
  }
  for (size_t i = 0; i < plain.textures.size(); ++i) {
    EXPECT_EQ(cv::norm(green.textures[i].image, plain.textures[i].image, cv::NORM_INF), 0);
  }
  for (size_t i = plain.surfaces.size(); i < green.surfaces.size(); ++i) {
    const SurfaceKind k = green.surfaces[i].kind;
    EXPECT_TRUE(k == SurfaceKind::kHedge || k == SurfaceKind::kTreeTrunk ||
                k == SurfaceKind::kTreeCrown);
  }
  const WorldOptions& o = green.options;
  const double road_m = o.margin_before_m + o.length_m + o.margin_after_m;
  const int slots = static_cast<int>(std::floor(road_m / o.vegetation.stretch_length_m));
  for (const int side : {-1, 1}) {
    double covered = 0;
    for (const VegetationStretch& v : green.vegetation) {
      if (v.side == side) covered += v.s1_m - v.s0_m;
    }
    std::printf("side %+d: %.1f of %.1f m with vegetation\n", side, covered, road_m);
    EXPECT_NEAR(covered / road_m, std::lround(0.5 * slots) / static_cast<double>(slots), 1e-9);
  }
  // Hedges stand within the stretches, on their side, beside the road.
  for (const Surface& s : green.surfaces) {
    if (s.kind != SurfaceKind::kHedge) continue;
    const RoadCoordinates rc = green.centreline.ToRoad(Centre(s).head<2>());
    bool inside = false;
    for (const VegetationStretch& v : green.vegetation) {
      inside =
          inside || (rc.s_m >= v.s0_m - 1e-6 && rc.s_m <= v.s1_m + 1e-6 && rc.d_m * v.side > 0);
    }
    EXPECT_TRUE(inside) << "hedge at s " << rc.s_m << " d " << rc.d_m;
    EXPECT_GT(std::abs(rc.d_m), o.road.asphalt_half_width_m() + 1.0);
  }
}

TEST(Vegetation, TexturesRepeatWithTheirPeriod) {
  const World& world = GreenWorld();
  const VegetationOptions& v = world.options.vegetation;
  int checked = 0;
  for (const Surface& s : world.surfaces) {
    if (s.kind != SurfaceKind::kHedge && s.kind != SurfaceKind::kTreeCrown &&
        s.kind != SurfaceKind::kTreeTrunk)
      continue;
    const Texture& t = world.textures[s.texture];
    const int period = static_cast<int>(std::lround(v.foliage_period_m / t.metres_per_pixel));
    EXPECT_NEAR(period * t.metres_per_pixel, v.foliage_period_m, 1e-12);
    // Along both axes where the texture is longer than a period (a trunk is narrower).
    ASSERT_GT(std::max(t.image.cols, t.image.rows), period);
    if (t.image.cols > period) {
      const cv::Mat a = t.image(cv::Rect(0, 0, t.image.cols - period, t.image.rows));
      const cv::Mat b = t.image(cv::Rect(period, 0, t.image.cols - period, t.image.rows));
      EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
    }
    if (t.image.rows > period) {
      const cv::Mat c = t.image(cv::Rect(0, 0, t.image.cols, t.image.rows - period));
      const cv::Mat d = t.image(cv::Rect(0, period, t.image.cols, t.image.rows - period));
      EXPECT_EQ(cv::norm(c, d, cv::NORM_INF), 0);
    }
    // Not a flat colour: the period carries the pattern.
    cv::Scalar mean, stddev;
    cv::meanStdDev(t.image, mean, stddev);
    EXPECT_GT(stddev[1], 8.0);
    ++checked;
  }
  EXPECT_GT(checked, 50);
}

TEST(Vegetation, TreesAreEvenlySpacedAndIdentical) {
  const World& world = GreenWorld();
  const VegetationOptions& v = world.options.vegetation;
  // Trunk centres (four faces each) per stretch, and the textures of all trunks and crowns.
  std::map<std::pair<int, double>, std::vector<double>> trunks;  // (side, s0) -> s of each trunk
  std::set<int> trunk_textures, crown_textures;
  std::vector<const Surface*> faces;
  for (const Surface& s : world.surfaces) {
    if (s.kind == SurfaceKind::kTreeCrown) crown_textures.insert(s.texture);
    if (s.kind != SurfaceKind::kTreeTrunk) continue;
    trunk_textures.insert(s.texture);
    faces.push_back(&s);
  }
  ASSERT_EQ(faces.size() % 4, 0u);
  int num_trees = 0;
  for (size_t i = 0; i < faces.size(); i += 4) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) c += 0.25 * Centre(*faces[i + k]);
    const RoadCoordinates rc = world.centreline.ToRoad(c.head<2>());
    for (const VegetationStretch& stretch : world.vegetation) {
      if (stretch.side * rc.d_m > 0 && rc.s_m > stretch.s0_m && rc.s_m < stretch.s1_m) {
        trunks[{stretch.side, stretch.s0_m}].push_back(rc.s_m);
      }
    }
    ++num_trees;
  }
  EXPECT_GT(num_trees, 10);
  EXPECT_EQ(trunk_textures.size(), 1u);  // one bark for all trees
  EXPECT_EQ(crown_textures.size(), 2u);  // one foliage, one darker underside
  for (auto& [stretch, s] : trunks) {
    std::sort(s.begin(), s.end());
    for (size_t i = 1; i < s.size(); ++i) {
      // Evenly spaced: neighbours one spacing apart, or a whole number of spacings where a tree
      // gave way to a pole.
      const double steps = (s[i] - s[i - 1]) / v.tree_spacing_m;
      EXPECT_NEAR(steps, std::round(steps), 1e-6);
      EXPECT_GE(std::round(steps), 1.0);
    }
  }
}

TEST(Vegetation, TreesCastShadows) {
  const World& world = GreenWorld();
  SunOptions noon;
  noon.elevation_deg = 90;
  const Lighting lighting(world, noon);
  int under = 0, shadowed = 0;
  for (const Surface& s : world.surfaces) {
    if (s.kind != SurfaceKind::kTreeCrown || s.Normal().z() == 0) continue;
    // Below the crown's underside, on the pavement beside the trunk: in the crown's shadow
    // (the underside itself is excluded as the receiver's own surface would be).
    const Eigen::Vector3d c = Centre(s);
    if (c.z() > 3.0) continue;  // the crown's top
    const Eigen::Vector3d p(c.x() + 0.6, c.y() + 0.6, world.options.road.kerb_height_m);
    ++under;
    shadowed += lighting.InShadow(p, -1);
  }
  EXPECT_GT(under, 10);
  EXPECT_EQ(shadowed, under);
  // And without vegetation the same points are lit.
  const Lighting plain_lighting(PlainWorld(), noon);
  int lit = 0;
  for (const Surface& s : world.surfaces) {
    if (s.kind != SurfaceKind::kTreeCrown || s.Normal().z() == 0) continue;
    const Eigen::Vector3d c = Centre(s);
    if (c.z() > 3.0) continue;
    lit += !plain_lighting.InShadow(
        Eigen::Vector3d(c.x() + 0.6, c.y() + 0.6, world.options.road.kerb_height_m), -1);
  }
  EXPECT_EQ(lit, under);  // nothing else stands there: trees keep clear of poles and signs
}

TEST(Vegetation, OptionsAreChecked) {
  WorldOptions o = Options(1.2);
  EXPECT_THROW(o.Check(), Error);
  o = Options(0.5);
  o.vegetation.tree_spacing_m = 2;
  EXPECT_THROW(BuildWorld(o), Error);
}

}  // namespace
}  // namespace epiloc
