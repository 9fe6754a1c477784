#include "epiloc/synth/drive_line.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Straight 40 m, a left arc of radius 30 m turning 90 deg, straight 40 m, a right arc of radius
// 50 m turning 30 deg (shorter than two ramps), straight 40 m.
Centreline TestStreet() {
  std::vector<CentrelinePiece> pieces;
  const auto add = [&](double length_m, double curvature_per_m) {
    CentrelinePiece p;
    if (!pieces.empty()) {
      const Centreline so_far(pieces);
      p.s0_m = so_far.end_s_m();
      p.start_in_world = so_far.PointAt(p.s0_m);
      p.start_yaw_rad = so_far.YawAt(p.s0_m);
    }
    p.length_m = length_m;
    p.curvature_per_m = curvature_per_m;
    pieces.push_back(p);
  };
  add(40, 0);
  add(30 * M_PI / 2, 1.0 / 30);
  add(40, 0);
  add(50 * M_PI / 6, -1.0 / 50);
  add(40, 0);
  return Centreline(pieces);
}

// Heading of the line from its positions (central difference) minus its stated heading, and the
// largest jump of position between close parameters, over [s0, s1].
void CheckSmooth(const DriveLine& line, double s0, double s1, double* heading_error_rad) {
  constexpr double h = 1e-4;
  *heading_error_rad = 0;
  for (double s = s0; s <= s1; s += 0.01) {
    const Eigen::Vector2d d = line.At(s + h).position_in_world - line.At(s - h).position_in_world;
    // Travelled distance per unit s stays near 1 (no jumps in position).
    ASSERT_LT(d.norm(), 2 * h * 1.2) << "s = " << s;
    ASSERT_GT(d.norm(), 2 * h * 0.8) << "s = " << s;
    const double yaw = std::atan2(d.y(), d.x());
    *heading_error_rad =
        std::max(*heading_error_rad, std::abs(std::remainder(yaw - line.At(s).yaw_rad, 2 * M_PI)));
  }
}

TEST(DriveLine, FollowsTheCentrelineExactlyWithoutVariants) {
  const Centreline street = TestStreet();
  const DriveLine line(street, -1.05);
  for (double s = -5; s < street.end_s_m() + 5; s += 0.37) {
    const LinePose pose = line.At(s);
    EXPECT_EQ(pose.position_in_world, street.PointAt(s, -1.05));
    EXPECT_EQ(pose.yaw_rad, street.YawAt(s));
    EXPECT_EQ(line.OffsetAt(s), -1.05);
  }
}

TEST(DriveLine, CutsTheInsideOfCurvesAndNothingOnStraights) {
  const Centreline street = TestStreet();
  DriveLine line(street, -1.75);
  line.SetCurveCut(1.2, 10.0);
  const std::vector<CentrelinePiece>& p = street.pieces();
  // On straights exactly the lane.
  for (const int i : {0, 2, 4}) {
    for (double s = p[i].s0_m; s <= p[i].s0_m + p[i].length_m; s += 0.5) {
      EXPECT_EQ(line.OffsetAt(s), -1.75) << s;
      EXPECT_EQ(line.At(s).position_in_world, street.PointAt(s, -1.75));
    }
  }
  // Left curve: towards the left (inside) by the full cut after the ramp; right curve (shorter
  // than two ramps): by the full cut in its middle only.
  const double left_mid = p[1].s0_m + 0.5 * p[1].length_m;
  EXPECT_NEAR(line.OffsetAt(left_mid), -1.75 + 1.2, 1e-12);
  EXPECT_NEAR(line.OffsetAt(p[1].s0_m + 10.0), -1.75 + 1.2, 1e-12);
  EXPECT_NEAR(line.OffsetAt(p[1].s0_m + 5.0), -1.75 + 0.6, 1e-12);  // smoothstep(0.5) = 0.5
  const double right_mid = p[3].s0_m + 0.5 * p[3].length_m;
  EXPECT_NEAR(line.OffsetAt(right_mid), -1.75 - 1.2, 1e-12);
  double max_cut = 0;
  for (double s = -5; s < street.end_s_m() + 5; s += 0.05) {
    max_cut = std::max(max_cut, std::abs(line.OffsetAt(s) + 1.75));
  }
  EXPECT_NEAR(max_cut, 1.2, 1e-6);
  double heading_error = 0;
  CheckSmooth(line, -5, street.end_s_m() + 5, &heading_error);
  std::printf("curve cut: heading from positions vs stated: max %.2e rad\n", heading_error);
  EXPECT_LT(heading_error, 1e-5);  // the difference straddles curvature jumps
}

TEST(DriveLine, TurnInFromASideStreetIsSmoothAndTurnsByTheAngle) {
  const Centreline street = TestStreet();
  for (const double turn_deg : {70.0, 90.0, 100.0}) {
    const double offset = -1.05, radius = 10.0, approach = 25.0, junction = 12.0;
    const Centreline lead_in = TurnInLeadIn(street, junction, turn_deg, offset, radius, approach);
    DriveLine line(street, offset);
    line.SetLeadIn(lead_in);
    const double join = junction + TurnInJoinDistance(turn_deg, offset, radius);
    EXPECT_NEAR(line.join_s_m(), join, 1e-12);
    EXPECT_NEAR(lead_in.start_s_m(), join - radius * turn_deg * kDeg - approach, 1e-9);
    // Heading change over the drive = the junction's angle (a right turn).
    const double start_yaw = line.At(lead_in.start_s_m()).yaw_rad;
    const double lane_yaw = line.At(join + 1.0).yaw_rad;
    EXPECT_NEAR(std::remainder(start_yaw - lane_yaw, 2 * M_PI), turn_deg * kDeg, 1e-12);
    // Continuous at both joins (approach -> arc -> lane).
    for (const double s : {lead_in.pieces()[1].s0_m, join}) {
      const LinePose before = line.At(s - 1e-9), after = line.At(s + 1e-9);
      EXPECT_LT((before.position_in_world - after.position_in_world).norm(), 1e-8) << s;
      EXPECT_LT(std::abs(std::remainder(before.yaw_rad - after.yaw_rad, 2 * M_PI)), 1e-8) << s;
    }
    double heading_error = 0;
    CheckSmooth(line, lead_in.start_s_m(), join + 20, &heading_error);
    EXPECT_LT(heading_error, 1e-5);  // the difference straddles curvature jumps
    // The approach runs parallel to the side street's axis (through the junction point, heading
    // turn_deg left of the street) at the lane's offset from it.
    const Eigen::Vector2d axis_point = street.PointAt(junction);
    const double axis_yaw = street.YawAt(junction) + turn_deg * kDeg;
    const Eigen::Vector2d axis_left(-std::sin(axis_yaw), std::cos(axis_yaw));
    for (double s = lead_in.start_s_m(); s < lead_in.pieces()[1].s0_m; s += 2.0) {
      EXPECT_NEAR((line.At(s).position_in_world - axis_point).dot(axis_left), offset, 1e-9);
      EXPECT_NEAR(std::remainder(line.At(s).yaw_rad - axis_yaw, 2 * M_PI), 0.0, 1e-12);
    }
    // On the arc the distance from its centre is the radius.
    const CentrelinePiece& arc = lead_in.pieces()[1];
    const Eigen::Vector2d right(std::sin(arc.start_yaw_rad), -std::cos(arc.start_yaw_rad));
    const Eigen::Vector2d centre = arc.start_in_world + radius * right;
    for (double s = arc.s0_m; s <= arc.s0_m + arc.length_m; s += 0.5) {
      EXPECT_NEAR((line.At(s).position_in_world - centre).norm(), radius, 1e-9);
    }
  }
  // A junction on the curve cannot be turned into with this geometry.
  EXPECT_THROW(TurnInLeadIn(street, 60.0, 90, -1.05, 10, 20), Error);
  EXPECT_THROW(TurnInLeadIn(street, 12.0, 20, -1.05, 10, 20), Error);
  DriveLine line(street, -1.75);
  EXPECT_THROW(line.SetLeadIn(TurnInLeadIn(street, 12.0, 90, -1.05, 10, 20)), Error);
}

}  // namespace
}  // namespace epiloc
