// Absolute camera pose from 2D-3D correspondences: PnP in a RANSAC loop (OpenCV USAC MAGSAC
// with P3P minimal solver and local optimisation) followed by a Levenberg-Marquardt refinement of
// the reprojection error over the inliers (cv::solvePnPRefineLM), re-selecting inliers after it.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/camera/camera.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

struct PnpOptions {
  double max_reprojection_px = 2.0;  // RANSAC inlier threshold, pixels
  double confidence = 0.9999;        // RANSAC confidence
  int max_iterations = 10000;        // RANSAC iterations at most
  int min_inliers = 12;              // fewer: no pose
  int refine_rounds = 2;             // LM refinement + inlier re-selection rounds (0 = none)
  // Groups of the grouped (delete-a-group) jackknife of the camera centre: the inliers are cut
  // into this many bands of image columns, and the pose is refined once without each band (0 or
  // fewer than 3 = not computed). See PnpResult::center_covariance_jackknife. Six: a street
  // scene's facades, roadside and the view ahead each fall in a band of their own, and the
  // estimate has 5 degrees of freedom per axis (3 bands: 2, too noisy to trust one frame's).
  int jackknife_groups = 6;
  // A band needs at least this many inliers (a region, not a lone point); fewer inliers, fewer
  // bands.
  int jackknife_min_group = 8;

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct PnpResult {
  bool success = false;
  Rigid3d cam_from_world;         // x_cam = R * x_world + t
  std::vector<char> inlier_mask;  // per correspondence
  int num_inliers = 0;
  double rmse_px = 0.0;  // reprojection RMSE over the inliers, pixels
  // Covariance of the camera centre in the world frame (m^2), from the inliers' Gauss-Newton
  // normal matrix and their residual scale; meaningful when success.
  Eigen::Matrix3d center_covariance = Eigen::Matrix3d::Zero();
  // The whole pose's covariance (rad^2, m^2): rotation first, as a perturbation
  // exp([dθ]x) applied on the left of cam_from_world's rotation, then the camera centre in the
  // world frame (ProjectionPoseJacobian propagates it to a point's projection).
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // The camera centre's covariance from the grouped jackknife over bands of image columns
  // (m^2): (K-1)/K times the scatter of the K centres refined without one band each. The model
  // covariance above assumes independent pixel errors; errors shared by a region of the image
  // (a part of the map triangulated wrong, a moving car, a pattern matched one period off) move
  // the centre when their band is left out, and show here. Zero when not computed.
  Eigen::Matrix3d center_covariance_jackknife = Eigen::Matrix3d::Zero();
  int jackknife_groups = 0;  // bands used (0: not computed)
  std::string message;  // why it failed ("" on success)
};

// The Jacobian (2x6) of the pixel projection of a point at camera coordinates `x_cam` (z > 0)
// with respect to the pose perturbation of PnpResult::pose_covariance: rotation exp([dθ]x) on the
// left of cam_from_world's rotation `rotation`, then the camera centre. x_cam = R (X - C) moves
// by -[x_cam]x dθ - R dC. With it the covariance of a projection is J * pose_covariance * J^T.
Eigen::Matrix<double, 2, 6> ProjectionPoseJacobian(const Camera& camera,
                                                   const Eigen::Vector3d& x_cam,
                                                   const Eigen::Matrix3d& rotation);

// Estimates cam_from_world from pixels `points2d` of the distortion-free pinhole `camera` and
// their world points `points3d` (same size). Expected failure (too few points or inliers) is a
// result with success = false and a message, not an exception; mismatched sizes throw Error.
PnpResult EstimateAbsolutePose(const std::vector<Eigen::Vector2d>& points2d,
                               const std::vector<Eigen::Vector3d>& points3d,
                               const Camera& camera,
                               const PnpOptions& options = PnpOptions());

}  // namespace epiloc
