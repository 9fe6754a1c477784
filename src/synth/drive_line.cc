#include "epiloc/synth/drive_line.h"

#include <cmath>
#include <limits>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Quintic smoothstep on [0, 1] (clamped): zero first and second derivatives at both ends.
double SmootherStep(double x, double* derivative) {
  if (x <= 0 || x >= 1) {
    *derivative = 0.0;
    return x <= 0 ? 0.0 : 1.0;
  }
  *derivative = 30 * x * x * (x * (x - 2) + 1);
  return x * x * x * (x * (6 * x - 15) + 10);
}

}  // namespace

DriveLine::DriveLine(const Centreline& centreline, double offset_m)
    : centreline_(centreline), offset_m_(offset_m) {
  EPILOC_CHECK(std::isfinite(offset_m), "drive line: offset is not finite");
}

void DriveLine::SetCurveCut(double cut_m, double ramp_m) {
  EPILOC_CHECK(std::isfinite(cut_m) && cut_m >= 0, "drive line: cut_m = {} must not be negative",
               cut_m);
  EPILOC_CHECK(std::isfinite(ramp_m) && ramp_m > 0, "drive line: ramp_m = {} must be positive",
               ramp_m);
  cut_m_ = cut_m;
  cuts_.clear();
  if (cut_m == 0) return;
  for (const CentrelinePiece& piece : centreline_.pieces()) {
    if (piece.curvature_per_m == 0) continue;
    Cut cut;
    cut.s0_m = piece.s0_m;
    cut.s1_m = piece.s0_m + piece.length_m;
    cut.ramp_m = std::min(ramp_m, 0.5 * piece.length_m);
    cut.sign = piece.curvature_per_m > 0 ? 1.0 : -1.0;
    cut.curvature_per_m = piece.curvature_per_m;
    cuts_.push_back(cut);
  }
}

void DriveLine::SetLeadIn(const Centreline& lead_in) {
  const double s = lead_in.end_s_m();
  const LinePose street = At(s);  // no lead-in yet: the street line
  const double yaw = lead_in.YawAt(s);
  EPILOC_CHECK((lead_in.PointAt(s) - street.position_in_world).norm() < 1e-6 &&
                   std::abs(std::remainder(yaw - street.yaw_rad, 2 * M_PI)) < 1e-9,
               "drive line: the lead-in does not end on the street line at s = {} m", s);
  lead_in_ = lead_in;
}

double DriveLine::join_s_m() const {
  return lead_in_ ? lead_in_->end_s_m() : -std::numeric_limits<double>::infinity();
}

double DriveLine::Offset(double s_m, double* derivative, const Cut** found) const {
  *derivative = 0.0;
  *found = nullptr;
  for (const Cut& cut : cuts_) {
    if (s_m <= cut.s0_m || s_m >= cut.s1_m) continue;
    double d_in = 0, d_out = 0;
    const double in = SmootherStep((s_m - cut.s0_m) / cut.ramp_m, &d_in);
    const double out = SmootherStep((cut.s1_m - s_m) / cut.ramp_m, &d_out);
    *found = &cut;
    // The ramps meet at most in the middle of the arc, where both are 1 with zero slope.
    if (in <= out) {
      *derivative = cut.sign * cut_m_ * d_in / cut.ramp_m;
      return offset_m_ + cut.sign * cut_m_ * in;
    }
    *derivative = -cut.sign * cut_m_ * d_out / cut.ramp_m;
    return offset_m_ + cut.sign * cut_m_ * out;
  }
  return offset_m_;
}

double DriveLine::OffsetAt(double s_m) const {
  double derivative = 0;
  const Cut* cut = nullptr;
  return Offset(s_m, &derivative, &cut);
}

LinePose DriveLine::At(double s_m) const {
  LinePose pose;
  if (lead_in_ && s_m < lead_in_->end_s_m()) {
    pose.position_in_world = lead_in_->PointAt(s_m);
    pose.yaw_rad = lead_in_->YawAt(s_m);
    return pose;
  }
  double derivative = 0;
  const Cut* cut = nullptr;
  const double offset = Offset(s_m, &derivative, &cut);
  pose.position_in_world = centreline_.PointAt(s_m, offset);
  pose.yaw_rad = centreline_.YawAt(s_m);
  if (cut != nullptr) {
    // d/ds (c(s) + offset(s) n(s)) = (1 - k offset) t + offset' n.
    pose.yaw_rad += std::atan2(derivative, 1.0 - cut->curvature_per_m * offset);
  }
  return pose;
}

double TurnInJoinDistance(double turn_deg, double offset_m, double radius_m) {
  // In the junction frame (x along the street, y to its left, the side street's axis through the
  // origin heading turn_deg left of x), the arc's centre lies at (x_join, offset - radius); the
  // approach line tangent to the arc at turn_deg has the lateral offset offset_m from the axis
  // exactly when x_join = (radius - offset) tan(turn / 2).
  return (radius_m - offset_m) * std::tan(0.5 * turn_deg * kDegToRad);
}

Centreline TurnInLeadIn(const Centreline& street,
                        double junction_s_m,
                        double turn_deg,
                        double offset_m,
                        double radius_m,
                        double approach_m) {
  EPILOC_CHECK(turn_deg >= 30 && turn_deg <= 150, "turn-in: turn_deg = {} must be in [30, 150]",
               turn_deg);
  EPILOC_CHECK(radius_m > 0 && std::isfinite(radius_m), "turn-in: radius_m must be positive");
  EPILOC_CHECK(approach_m > 0 && std::isfinite(approach_m), "turn-in: approach_m must be positive");
  const double join_s = junction_s_m + TurnInJoinDistance(turn_deg, offset_m, radius_m);
  EPILOC_CHECK(join_s > junction_s_m, "turn-in: the turn of radius {} m cannot reach offset {} m",
               radius_m, offset_m);
  const CentrelinePiece& piece = street.pieces()[street.PieceAt(junction_s_m)];
  EPILOC_CHECK(piece.curvature_per_m == 0 && piece.s0_m <= junction_s_m &&
                   piece.s0_m + piece.length_m >= join_s,
               "turn-in: the street is not straight from the junction at s = {} m to the join at "
               "s = {} m",
               junction_s_m, join_s);
  const double phi = turn_deg * kDegToRad;
  const double yaw = street.YawAt(join_s);
  const Eigen::Vector2d join = street.PointAt(join_s, offset_m);
  const Eigen::Vector2d left(-std::sin(yaw), std::cos(yaw));
  const Eigen::Vector2d centre = join - radius_m * left;  // a right turn: centre on the right
  const Eigen::Vector2d from_centre = join - centre;
  const Eigen::Vector2d arc_start =
      centre + Eigen::Vector2d(std::cos(phi) * from_centre.x() - std::sin(phi) * from_centre.y(),
                               std::sin(phi) * from_centre.x() + std::cos(phi) * from_centre.y());
  const double heading = yaw + phi;
  const Eigen::Vector2d direction(std::cos(heading), std::sin(heading));
  CentrelinePiece approach;
  approach.s0_m = join_s - radius_m * phi - approach_m;
  approach.length_m = approach_m;
  approach.start_in_world = arc_start - approach_m * direction;
  approach.start_yaw_rad = heading;
  CentrelinePiece arc;
  arc.s0_m = join_s - radius_m * phi;
  arc.length_m = radius_m * phi;
  arc.start_in_world = arc_start;
  arc.start_yaw_rad = heading;
  arc.curvature_per_m = -1.0 / radius_m;
  return Centreline({approach, arc});
}

}  // namespace epiloc
