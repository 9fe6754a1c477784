// Similarity transforms (Sim(3)) between a monocular trajectory's frame and a metric frame, and
// the least-squares fit of one to point pairs (Umeyama 1991, via Eigen::umeyama).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "epiloc/geo/rigid3.h"

namespace epiloc {

// b_from_a with scale: x_in_b = scale * R * x_in_a + t.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x_in_a) const {
    return scale * (rotation * x_in_a) + translation;
  }
  // A pose world_a_from_cam mapped to world_b_from_cam (rotation composed, centre mapped; the
  // camera frame keeps its metric, so the scale applies to the centre only).
  Rigid3d MapPose(const Rigid3d& a_from_cam) const {
    return Rigid3d(rotation * a_from_cam.rotation, *this * a_from_cam.translation);
  }
  Sim3d Inverse() const;
};

// Least-squares similarity taking `source[i]` to `target[i]` (Umeyama): minimises
// sum |target - (s R source + t)|^2. Needs >= 3 pairs not all on one line; returns nullopt when
// the source points are (near) collinear (second singular value of the centred points below
// `min_spread_ratio` of the first), where the rotation about the line is not determined.
std::optional<Sim3d> FitSim3(const std::vector<Eigen::Vector3d>& source,
                             const std::vector<Eigen::Vector3d>& target,
                             double min_spread_ratio = 1e-3);

// The same with the rotation also fitted to known rotations `target_from_source[i]` (e.g. anchor
// orientation * VO orientation^-1): R maximises tr(R^T M), M = the point pairs' cross-covariance
// normalised by scale and spread, plus the mean of the given rotations (Wahba's problem, solved
// by SVD); then scale and translation by least squares given R. Positions determine R along
// their spread, the rotations everywhere else: a nearly straight path no longer leaves the roll
// about it to noise. Needs >= 2 pairs with distinct sources and one rotation per pair; nullopt
// otherwise (or for a non-positive scale).
std::optional<Sim3d> FitSim3(const std::vector<Eigen::Vector3d>& source,
                             const std::vector<Eigen::Vector3d>& target,
                             const std::vector<Eigen::Quaterniond>& target_from_source);

// Root mean square and maximum of |target - sim * source| over the pairs.
struct FitResiduals {
  double rms_m = 0.0;
  double max_m = 0.0;
};
FitResiduals Residuals(const Sim3d& sim,
                       const std::vector<Eigen::Vector3d>& source,
                       const std::vector<Eigen::Vector3d>& target);

}  // namespace epiloc
