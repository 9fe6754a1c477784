// Bundle adjustment of the monocular odometry (Ceres): local BA over keyframes and points, and
// motion-only pose refinement of one frame. Residuals are reprojection errors in pixels
// (normalised-coordinate error times `focal_px`) under a Huber loss.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "epiloc/geo/rigid3.h"

namespace epiloc {

struct BundleOptions {
  double focal_px = 500.0;  // converts normalised-coordinate residuals to pixels
  double huber_px = 2.0;    // Huber loss scale, pixels
  int max_iterations = 10;  // Levenberg-Marquardt iterations
  int num_threads = 1;      // Ceres threads

  // Throws Error naming the first invalid field.
  void Check() const;
};

// One observation: point `point` seen by pose `pose` at normalised coordinates `x`.
struct BundleObservation {
  int pose = 0;
  int point = 0;
  Eigen::Vector2d x = Eigen::Vector2d::Zero();
};

// The problem, adjusted in place. Poses are cam_from_world (x_in_cam = R * x_in_world + t).
// A monocular problem needs at least two fixed poses (or a fixed pose and fixed points) to fix
// its gauge including the scale; the solver does not add any.
struct BundleProblem {
  std::vector<Rigid3d> cam_from_world;
  std::vector<bool> pose_fixed;  // same size as cam_from_world
  std::vector<Eigen::Vector3d> points_in_world;
  std::vector<BundleObservation> observations;
  // Optionally one free pose of which only translation coordinate `scale_axis` (0..2) is held:
  // with one fixed pose, the scale gauge of a monocular problem that leaves the rest free.
  int scale_pose = -1;
  int scale_axis = 0;
};

struct BundleSummary {
  bool solved = false;  // Ceres returned a usable solution
  int iterations = 0;
  double initial_rms_px = 0.0;  // root mean square reprojection error before and after
  double final_rms_px = 0.0;
  double seconds = 0.0;
};

// Adjusts the free poses and all points of `problem` (points seen by a fixed pose only stay
// adjustable). Throws Error for indices out of range.
BundleSummary SolveBundle(BundleProblem& problem, const BundleOptions& options);

// Motion-only adjustment: refines one pose from 2D-3D correspondences (points fixed) by robust
// least squares starting at `cam_from_world`, then re-estimates on the inliers (error <=
// max_error_px) once more.
struct MotionOnlyResult {
  Rigid3d cam_from_world;
  std::vector<bool> inliers;  // per correspondence, error <= max_error_px after refinement
  int num_inliers = 0;
  double rms_px = 0.0;  // over the inliers
};
MotionOnlyResult RefineMotionOnly(const Rigid3d& cam_from_world,
                                  const std::vector<Eigen::Vector3d>& points_in_world,
                                  const std::vector<Eigen::Vector2d>& x,
                                  double max_error_px,
                                  const BundleOptions& options);

}  // namespace epiloc
