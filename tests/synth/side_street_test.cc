#include "epiloc/synth/side_street.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/trajectory.h"
#include "epiloc/synth/world.h"

namespace epiloc {
namespace {

constexpr double kDeg = M_PI / 180.0;

WorldOptions SideStreetWorldOptions(double angle_deg) {
  WorldOptions o;
  o.length_m = 80;
  o.margin_after_m = 30;
  o.seed = 2;
  o.side_street.enabled = true;
  o.side_street.angle_deg = angle_deg;
  o.side_street.at_m = 20;
  return o;
}

bool Obstacle(SurfaceKind kind) {
  return kind == SurfaceKind::kFacade || kind == SurfaceKind::kWall ||
         kind == SurfaceKind::kBackground || kind == SurfaceKind::kPole ||
         kind == SurfaceKind::kSign || kind == SurfaceKind::kCar;
}

double SegmentDistance(const Eigen::Vector2d& p,
                       const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double f =
      ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  return (a + f * ab - p).norm();
}

// Horizontal distance from `p` to the nearest obstacle (the footprint edges of upright quads
// and car roofs), and its kind.
double ObstacleDistance(const World& world, const Eigen::Vector2d& p, SurfaceKind* kind) {
  double best = 1e9;
  for (const Surface& s : world.surfaces) {
    if (!Obstacle(s.kind)) continue;
    for (int i = 0; i < 4; ++i) {
      const double d = SegmentDistance(p, s.corners_in_world[i].head<2>(),
                                       s.corners_in_world[(i + 1) % 4].head<2>());
      if (d < best) {
        best = d;
        *kind = s.kind;
      }
    }
  }
  return best;
}

TEST(SideStreet, JoinsTheStreetWithNothingInTheWay) {
  for (const double angle : {90.0, 75.0}) {
    const World world = BuildWorld(SideStreetWorldOptions(angle));
    ASSERT_TRUE(world.side_street.has_value());
    const SideStreet& side = *world.side_street;
    EXPECT_NEAR(side.angle_deg, angle, 1e-12);
    // On a straight of the street, near the wanted place.
    const CentrelinePiece& piece =
        world.centreline.pieces()[world.centreline.PieceAt(side.junction_s_m)];
    EXPECT_EQ(piece.curvature_per_m, 0.0);
    EXPECT_LE(piece.s0_m, side.straight_from_s_m);
    EXPECT_GE(piece.s0_m + piece.length_m, side.straight_to_s_m);
    // The axis leaves to the right at the angle.
    const double street_yaw = world.centreline.YawAt(side.junction_s_m);
    EXPECT_NEAR(std::remainder(std::atan2(-side.away.y(), -side.away.x()) - street_yaw, 2 * M_PI),
                angle * kDeg, 1e-12);
    // Its asphalt: road surfaces beside the street, and nothing standing within 3 m of it (the
    // building fronts stand 3 m behind the kerb, as along the street).
    const double half = world.options.road.asphalt_half_width_m();
    const Eigen::Vector2d b(-side.away.y(), side.away.x());
    int side_roads = 0;
    for (const Surface& s : world.surfaces) {
      const Eigen::Vector2d c = 0.25 * (s.corners_in_world[0] + s.corners_in_world[1] +
                                        s.corners_in_world[2] + s.corners_in_world[3])
                                           .head<2>();
      if (s.kind == SurfaceKind::kRoad && std::abs(world.centreline.ToRoad(c).d_m) > half + 5.0)
        ++side_roads;
    }
    EXPECT_GE(side_roads, 1);
    double nearest = 1e9;
    SurfaceKind nearest_kind = SurfaceKind::kGround;
    const double r0 = half / std::sin(angle * kDeg) + half / std::tan(angle * kDeg) + 0.5;
    for (double r = r0; r <= side.end_r_m; r += 1.0) {
      for (double w = -half; w <= half + 1e-9; w += half / 4) {
        SurfaceKind kind;
        const double d =
            ObstacleDistance(world, side.junction_in_world + r * side.away + w * b, &kind);
        if (d < nearest) {
          nearest = d;
          nearest_kind = kind;
        }
      }
    }
    std::printf("%.0f deg: junction at s = %.1f m, nearest obstacle to its asphalt %.2f m (%s)\n",
                angle, side.junction_s_m, nearest, SurfaceKindName(nearest_kind));
    EXPECT_GT(nearest, 2.9);
    // Markers still sit on facades after the surfaces were removed and added.
    for (const Marker& m : world.markers) {
      ASSERT_GE(m.surface, 0);
      ASSERT_LT(m.surface, static_cast<int>(world.surfaces.size()));
      EXPECT_EQ(world.surfaces[m.surface].kind, SurfaceKind::kFacade);
      EXPECT_TRUE(world.surfaces[m.surface].Contains(m.position_in_world));
    }
  }
}

TEST(SideStreet, QueryTurnsInOnAsphaltWithAClearView) {
  const World world = BuildWorld(SideStreetWorldOptions(90.0));
  DriveOptions drive = DriveOptions::Query();
  drive.turn_in = true;
  const DrivePath path(world, drive, world.options.length_m, 1);
  const DriveLine& line = path.line();
  ASSERT_TRUE(line.lead_in().has_value());
  const double start = path.start_s_m(), join = line.join_s_m();
  // The drive starts on the side street, away from the street, and ends on its lane.
  const Eigen::Vector3d first = path.CamFromWorld(path.start_time_s()).Inverse().translation;
  EXPECT_GT(std::abs(world.centreline.ToRoad(first.head<2>()).d_m), 25.0);
  EXPECT_NEAR(std::remainder(line.At(start).yaw_rad - line.At(join + 1).yaw_rad, 2 * M_PI),
              90.0 * kDeg, 1e-12);
  // Half a car's width (0.9 m) plus 0.6 m from anything standing, all the way.
  double nearest = 1e9;
  for (double s = start; s <= join + 30; s += 0.25) {
    SurfaceKind kind;
    nearest = std::min(nearest, ObstacleDistance(world, line.At(s).position_in_world, &kind));
    EXPECT_TRUE(world.side_street->OnAsphalt(world, line.At(s).position_in_world, 0.9)) << s;
  }
  std::printf("turn in: nearest obstacle %.2f m from the path\n", nearest);
  EXPECT_GT(nearest, 1.5);
  // The first frame looks down the side street at the street's far side: the image centre sees
  // far, the bottom centre sees asphalt.
  RenderOptions options;
  options.depth = options.surface_ids = true;
  const Renderer renderer(drive.camera, options);
  const RenderResult r = renderer.Render(world, path.CamFromWorld(path.start_time_s()));
  const int cx = drive.camera.width / 2;
  const float centre_depth = r.depth.at<float>(drive.camera.height / 2, cx);
  const int bottom = r.surface_id.at<int>(drive.camera.height - 5, cx);
  std::printf("first frame: %.1f m deep at the centre\n", centre_depth);
  EXPECT_TRUE(centre_depth == 0 || centre_depth > 30.0);
  ASSERT_GE(bottom, 0);
  EXPECT_EQ(world.surfaces[bottom].kind, SurfaceKind::kRoad);
  // The speed through the turn respects the lateral acceleration limit.
  const CentrelinePiece& arc = line.lead_in()->pieces()[1];
  const double t0 = path.TimeAtS(arc.s0_m), t1 = path.TimeAtS(arc.s0_m + arc.length_m);
  const double v_max = std::sqrt(drive.turn_lateral_accel_mps2 * drive.turn_radius_m);
  for (double t = t0; t + 0.1 <= t1; t += 0.1) {
    EXPECT_LE((path.SAt(t + 0.1) - path.SAt(t)) / 0.1, v_max * 1.001);
  }
}

TEST(SideStreet, OptionsAreChecked) {
  WorldOptions o = SideStreetWorldOptions(40.0);
  EXPECT_THROW(o.Check(), Error);
  o = SideStreetWorldOptions(90.0);
  o.side_street.length_m = 10;
  EXPECT_THROW(o.Check(), Error);
  // A street without a long enough straight.
  o = SideStreetWorldOptions(90.0);
  o.min_straight_m = o.max_straight_m = 10;
  o.margin_before_m = 5;
  o.min_radius_m = o.max_radius_m = 25;
  o.max_turn_deg = 90;
  EXPECT_THROW(BuildWorld(o), Error);
}

}  // namespace
}  // namespace epiloc
