// Metric 6-DoF refinement of a localized query frame against the survey's triangulated points:
// the query features the epipolar step matched to database features that see a 3-D point
// (PairResult::point_matches, all pairs of the frame) become 2D-3D correspondences, and PnP
// RANSAC + LM (geometry/absolute_pose.h) gives the camera pose in the database ENU frame.
//
// Correspondences: a query feature matched to several database frames votes for their points;
// the point with most votes wins (ties: the first seen), so one query feature gives at most one
// correspondence. The world points are shifted to their centroid before PnP (numerics).
//
// Outcomes (RefineStatus): kOk; kThin when there are fewer than min_correspondences or PnP
// finds fewer than min_inliers (the caller falls back to the epipolar estimate, flagged);
// kRejected when the pose disagrees with the epipolar sequence estimate by more than
// max_along_disagreement_m along the route or lies more than max_cross_track_m off the route
// (a wrong pose is not reported).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "epiloc/camera/camera.h"
#include "epiloc/feature/types.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/geo/route.h"
#include "epiloc/geometry/absolute_pose.h"
#include "epiloc/localize/pair_evaluator.h"

namespace epiloc {

struct RefineOptions {
  bool enabled = true;           // run the refinement when the database has structure
  int min_correspondences = 20;  // fewer 2D-3D correspondences: thin structure
  int min_inliers = 15;          // fewer PnP inliers: thin structure
  // |s_pnp - s_reference| above this: rejected before the tracker weighs the pose (beyond a
  // window the local map around the reference no longer holds the true place).
  double max_along_disagreement_m = 8.0;
  double max_cross_track_m = 8.0;  // farther from the route: rejected
  PnpOptions pnp = DefaultPnp();
  // Search by projection (RefineByProjection): radius around each projected point, largest
  // RootSIFT distance accepted, ratio of best to second best within the radius.
  bool search_by_projection = true;
  double search_radius_px = 4.0;
  // A point is searched only when the initial pose predicts its projection to within the radius
  // at this many standard deviations (the major axis of its 2-D covariance; 3: 99 % of a 2-D
  // Gaussian). When fewer than half of the projected points are, this search does not run from
  // the initial pose: its errors reach beyond the radius, and what the search finds near the
  // wrong projections is a consistent but wrong set of matches that only shrinks the covariance
  // (a turn into the street, viewing the survey's structure 60-70 degrees across).
  double search_sigmas = 3.0;
  double max_descriptor_distance = 0.7;
  double search_ratio = 0.9;
  // Then the wide search (else the initial pose is kept): each point within search_sigmas standard
  // deviations of its projection (at least search_radius_px), the pose's covariance scaled up to
  // its along-route sigma (the jackknife's when larger), with the same descriptor distance and
  // ratio; PnP on what it finds and, when that pose has more inliers, the search above from it. The
  // true feature lies within the searched region, and the descriptor, not the nearness to the wrong
  // projection, picks it; a pattern repeated within the region fails the ratio test.
  bool wide_search = true;
  // Database frames searched by projection: from this far behind the estimate (to
  // local_map_ahead_m ahead of it). A camera turned across the street (entering it from a side
  // road) sees the points beside it, and the survey's forward-looking camera saw those from
  // behind: from lateral offset / tan(half its horizontal field of view). Facades 10 m to the side
  // (two lanes, parking and pavement) and a half field of view of 34 degrees (800 px at fx 600, the
  // synthetic survey; KITTI's 1242 px at fx 721: 41 degrees, 11.6 m) give 15 m. With 2 m the search
  // found 45-52 of the ~190 points the query sees in synth_turn_in's turn.
  double local_map_behind_m = 15.0;
  double local_map_ahead_m = 10.0;

  void Check() const;
  static PnpOptions DefaultPnp();
};

enum class RefineStatus { kOk, kThin, kRejected };
const char* RefineStatusName(RefineStatus status);

struct PoseRefinement {
  RefineStatus status = RefineStatus::kThin;
  std::string message;         // why not ok ("" when ok)
  Rigid3d enu_from_cam;        // camera pose in the database ENU frame (when ok)
  RouteProjection projection;  // its camera centre on the route (when ok)
  int num_correspondences = 0;
  int num_inliers = 0;
  double rmse_px = 0.0;
  // Standard deviations of the camera centre (when ok): along the route and horizontally (the
  // root of the horizontal covariance's trace), metres; each the larger of the PnP model
  // covariance's and the jackknife's (PnpResult::center_covariance_jackknife) ...
  double sigma_along_m = 0.0;
  double sigma_horizontal_m = 0.0;
  // ... and along the route from the model covariance alone (independent pixel errors).
  double sigma_along_model_m = 0.0;
  // The pose's covariance (PnpResult::pose_covariance: rotation of cam_from_enu, camera centre).
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

// Refines the pose of a query frame (undistorted pinhole `camera`, its `keypoints`) from the
// point matches of its evaluated `pairs`; `s_epipolar_m` is the sequence estimate it must agree
// with, `route` the database route.
PoseRefinement RefinePose(const Camera& camera,
                          const FeatureKeypoints& keypoints,
                          const std::vector<PairResult>& pairs,
                          double s_epipolar_m,
                          const Route& route,
                          const RefineOptions& options);

// Search by projection (as feature-based SLAM tracks its local map): the points the window's
// database frames see are projected with the `initial` pose (kOk); each is matched to the query
// feature within search_radius_px of its projection (when the initial pose's covariance predicts
// it that closely, see search_sigmas) with the nearest RootSIFT descriptor (at
// most max_descriptor_distance, and below search_ratio times the second nearest within the
// radius; a feature claimed by several points keeps the closest descriptor); PnP again on these
// correspondences, with the same checks. When the initial pose predicts too few projections that
// closely, the wide search (RefineOptions::wide_search) runs first. Returns the new pose if it is
// ok with more inliers than `initial`, else `initial`. `query_root_sift`: 128 floats per keypoint
// row (ToRootSift).
PoseRefinement RefineByProjection(
    const Camera& camera,
    const FeatureKeypoints& keypoints,
    const std::vector<float>& query_root_sift,
    const std::vector<std::shared_ptr<const FrameMapPoints>>& local_map,
    const PoseRefinement& initial,
    double s_epipolar_m,
    const Route& route,
    const RefineOptions& options);

}  // namespace epiloc
