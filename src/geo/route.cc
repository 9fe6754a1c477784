#include "epiloc/geo/route.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "epiloc/core/error.h"

namespace epiloc {

Route::Route(const std::vector<Eigen::Vector3d>& points_in_enu, double min_spacing_m) {
  for (const auto& p : points_in_enu) {
    EPILOC_CHECK(p.allFinite(), "route: non-finite point");
    if (points_.empty() || (p - points_.back()).head<2>().norm() >= min_spacing_m) {
      points_.push_back(p);
    }
  }
  EPILOC_CHECK(points_.size() >= 2, "route: needs at least two distinct positions, got {}",
               points_.size());
  cumulative_s_.resize(points_.size(), 0.0);
  for (size_t i = 1; i < points_.size(); ++i) {
    cumulative_s_[i] = cumulative_s_[i - 1] + (points_[i] - points_[i - 1]).head<2>().norm();
  }
}

RouteProjection Route::ProjectOnSegment(const Eigen::Vector3d& p, int i) const {
  const Eigen::Vector2d a = points_[i].head<2>();
  const Eigen::Vector2d b = points_[i + 1].head<2>();
  const Eigen::Vector2d ab = b - a;
  const double length = ab.norm();
  const Eigen::Vector2d dir = ab / length;
  double t = (p.head<2>() - a).dot(dir);
  const bool first = i == 0;
  const bool last = i + 2 == static_cast<int>(points_.size());
  RouteProjection proj;
  proj.within = t >= 0.0 && t <= length;
  // Interior segments clamp; the end segments extend so s keeps growing beyond the ends.
  if (!(first && t < 0.0) && !(last && t > length)) t = std::clamp(t, 0.0, length);
  const Eigen::Vector2d foot = a + t * dir;
  const Eigen::Vector2d offset = p.head<2>() - foot;
  proj.s_m = cumulative_s_[i] + t;
  proj.cross_track_m = dir.x() * offset.y() - dir.y() * offset.x();  // left of travel is positive
  const double alpha = std::clamp(t / length, 0.0, 1.0);
  proj.vertical_m = p.z() - ((1 - alpha) * points_[i].z() + alpha * points_[i + 1].z());
  proj.segment = i;
  if (!proj.within) proj.within = std::abs(offset.dot(dir)) < 1e-9;
  return proj;
}

RouteProjection Route::ProjectRange(const Eigen::Vector3d& p, int first, int last) const {
  RouteProjection best;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int i = first; i <= last; ++i) {
    const RouteProjection proj = ProjectOnSegment(p, i);
    const Eigen::Vector2d foot = PointAt(proj.s_m).head<2>();
    const double distance = (p.head<2>() - foot).norm();
    if (distance < best_distance - 1e-12) {
      best_distance = distance;
      best = proj;
    }
  }
  best.within = best.s_m >= 0.0 && best.s_m <= length_m();
  return best;
}

RouteProjection Route::Project(const Eigen::Vector3d& p) const {
  return ProjectRange(p, 0, static_cast<int>(points_.size()) - 2);
}

RouteProjection Route::ProjectNear(const Eigen::Vector3d& p,
                                   double s_hint_m,
                                   double window_m) const {
  const int first = SegmentAt(s_hint_m - window_m);
  const int last = SegmentAt(s_hint_m + window_m);
  return ProjectRange(p, first, last);
}

int Route::SegmentAt(double s_m) const {
  const auto it = std::upper_bound(cumulative_s_.begin(), cumulative_s_.end(), s_m);
  const int index = static_cast<int>(it - cumulative_s_.begin()) - 1;
  return std::clamp(index, 0, static_cast<int>(points_.size()) - 2);
}

Eigen::Vector3d Route::PointAt(double s_m) const {
  const int i = SegmentAt(s_m);
  const double length = cumulative_s_[i + 1] - cumulative_s_[i];
  const double alpha = (s_m - cumulative_s_[i]) / length;
  return points_[i] + alpha * (points_[i + 1] - points_[i]);
}

Eigen::Vector3d Route::DirectionAt(double s_m) const {
  const int i = SegmentAt(s_m);
  Eigen::Vector3d d = points_[i + 1] - points_[i];
  d.z() = 0.0;
  return d.normalized();
}

}  // namespace epiloc
