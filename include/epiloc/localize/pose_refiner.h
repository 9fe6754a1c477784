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
  bool enabled = true;              // run the refinement when the database has structure
  int min_correspondences = 20;     // fewer 2D-3D correspondences: thin structure
  int min_inliers = 15;             // fewer PnP inliers: thin structure
  double max_along_disagreement_m = 1.5;  // |s_pnp - s_epipolar| above this: rejected
  double max_cross_track_m = 8.0;   // farther from the route: rejected
  PnpOptions pnp = DefaultPnp();

  void Check() const;
  static PnpOptions DefaultPnp();
};

enum class RefineStatus { kOk, kThin, kRejected };
const char* RefineStatusName(RefineStatus status);

struct PoseRefinement {
  RefineStatus status = RefineStatus::kThin;
  std::string message;              // why not ok ("" when ok)
  Rigid3d enu_from_cam;             // camera pose in the database ENU frame (when ok)
  RouteProjection projection;       // its camera centre on the route (when ok)
  int num_correspondences = 0;
  int num_inliers = 0;
  double rmse_px = 0.0;
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

}  // namespace epiloc
