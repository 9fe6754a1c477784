// The route: a polyline through survey camera positions in a database's ENU frame, with the
// along-route distance s (metres from the first point) as its coordinate.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace epiloc {

// Where a point lies relative to the route.
struct RouteProjection {
  double s_m = 0.0;            // along-route distance of the foot point; < 0 or > length beyond the ends
  double cross_track_m = 0.0;  // horizontal signed offset, positive to the left of travel direction
  double vertical_m = 0.0;     // point altitude minus route altitude at s
  int segment = 0;             // index of the segment [i, i+1] holding the foot point
  bool within = true;          // foot point lies on the polyline (not on the extension of an end)
};

class Route {
 public:
  // `points_in_enu` in travel order. Consecutive points closer than `min_spacing_m` horizontally
  // are merged (a stopped vehicle). Throws Error if fewer than two distinct points remain.
  explicit Route(const std::vector<Eigen::Vector3d>& points_in_enu, double min_spacing_m = 0.01);

  double length_m() const { return cumulative_s_.back(); }
  const std::vector<Eigen::Vector3d>& points() const { return points_; }
  // Along-route distance of each kept point.
  const std::vector<double>& cumulative_s() const { return cumulative_s_; }

  // Horizontal (E, N) projection onto the nearest segment; the first and last segments extend
  // beyond the ends so a point before the start gets s < 0.
  RouteProjection Project(const Eigen::Vector3d& point_in_enu) const;
  // Same, considering only segments that overlap [s_hint - window_m, s_hint + window_m]
  // (a route that passes the same place twice).
  RouteProjection ProjectNear(const Eigen::Vector3d& point_in_enu,
                              double s_hint_m,
                              double window_m) const;

  // Position at along-route distance s (linear interpolation, extrapolated beyond the ends).
  Eigen::Vector3d PointAt(double s_m) const;
  // Unit horizontal travel direction (E, N, 0) at s.
  Eigen::Vector3d DirectionAt(double s_m) const;

 private:
  int SegmentAt(double s_m) const;
  RouteProjection ProjectOnSegment(const Eigen::Vector3d& p, int segment) const;
  RouteProjection ProjectRange(const Eigen::Vector3d& p, int first, int last) const;

  std::vector<Eigen::Vector3d> points_;
  std::vector<double> cumulative_s_;
};

}  // namespace epiloc
