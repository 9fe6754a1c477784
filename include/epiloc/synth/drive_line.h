// The planar line a synthetic drive follows: any smooth path in the world's ENU plane (continuous
// in position and heading), as a function of a parameter s in metres.
//
// On the street the line follows the centreline at a lateral offset, and s is the centreline's
// along-road distance of the foot point, so every drive on the street shares s with the survey and
// the world. The offset may vary smoothly (a drive cutting the inside of curves). An optional
// lead-in (a chain of straights and arcs, e.g. along a side street and through a turn) joins the
// street line at its end; on the lead-in s is the distance travelled, continuing the street's s
// backwards from the join.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "epiloc/synth/centreline.h"

namespace epiloc {

// Where on its line a drive is.
struct LinePose {
  Eigen::Vector2d position_in_world = Eigen::Vector2d::Zero();  // (east, north), metres
  double yaw_rad = 0.0;  // travel direction, counter-clockwise from east
};

class DriveLine {
 public:
  // Follows `centreline` at the lateral offset `offset_m` (positive left of the travel direction).
  DriveLine(const Centreline& centreline, double offset_m);

  // Cuts the inside of every arc of the centreline by up to `cut_m` (>= 0): the offset moves
  // towards the arc's centre along a quintic smoothstep over the first `ramp_m` of the arc (at
  // most half its length), stays at `cut_m` and moves back over its last `ramp_m`. The offset is
  // C2, so position and heading stay continuous (curvature too, except where the centreline's own
  // curvature jumps); on straights the offset is exactly `offset_m`. Throws Error for a negative
  // cut or a non-positive ramp.
  void SetCurveCut(double cut_m, double ramp_m);
  // Drives `lead_in` before joining the street line at lead_in.end_s_m(). Its end must meet the
  // street line's pose there (1e-6 m, 1e-9 rad), else throws Error.
  void SetLeadIn(const Centreline& lead_in);

  // Pose at s; beyond the lead-in's start its first piece continues, beyond the street's ends the
  // centreline's end pieces continue.
  LinePose At(double s_m) const;
  // Lateral offset from the centreline on the street part (the lead-in ignored).
  double OffsetAt(double s_m) const;

  const Centreline& centreline() const { return centreline_; }
  double offset_m() const { return offset_m_; }
  // The lead-in, if any; the street line starts at its end.
  const std::optional<Centreline>& lead_in() const { return lead_in_; }
  // Where the lead-in joins the street line.
  double join_s_m() const;

 private:
  // One arc of the centreline whose inside is cut.
  struct Cut {
    double s0_m = 0.0, s1_m = 0.0;  // the arc's extent
    double ramp_m = 0.0;            // length of the smoothstep at each end
    double sign = 0.0;              // +1 for a left curve (inside = positive offsets), -1 right
    double curvature_per_m = 0.0;
  };
  // Offset and its derivative d(offset)/ds on the street part; `cut` (if found) receives the arc.
  double Offset(double s_m, double* derivative, const Cut** cut) const;

  Centreline centreline_;
  double offset_m_ = 0.0;
  double cut_m_ = 0.0;
  std::vector<Cut> cuts_;
  std::optional<Centreline> lead_in_;
};

// The lead-in of a drive that comes along a side street joining the street's right side at the
// centreline distance `junction_s_m` and turns right by `turn_deg` into the street: a straight of
// `approach_m` on the side street (whose axis runs through the junction point, heading `turn_deg`
// left of the street's travel direction), at the lateral offset `offset_m` from that axis (the
// same offset from its centre as on the street), then an arc of `radius_m` that ends tangentially
// on the street line at `offset_m`. The centreline must be straight from the junction to the join;
// throws Error otherwise or for a radius or angle out of range (turn in [30, 150] deg, radius > 0).
Centreline TurnInLeadIn(const Centreline& street,
                        double junction_s_m,
                        double turn_deg,
                        double offset_m,
                        double radius_m,
                        double approach_m);

// Distance along the street from the junction to where the turn of TurnInLeadIn joins the line.
double TurnInJoinDistance(double turn_deg, double offset_m, double radius_m);

}  // namespace epiloc
