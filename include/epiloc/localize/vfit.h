// Sub-frame position of a query frame from its epipolar distances to nearby database frames:
// Kyutoku et al., "Epipolar geometry-based ego-localization using an in-vehicle monocular camera",
// sec. 2.2. The image distance d = 1/|e_x| of the query frame against a database frame at along-
// route distance s grows linearly with |s - l|, l the query's own along-route position (eq. 3):
//
//   d = a |s - l|,  a > 0   (a V with its vertex at l; a = 1 / (f |q_x|) per metre).
//
// When the side of each database camera is known (the sign of q_z, as in the sign of
// EpipoleResult::signed_distance: database camera ahead = positive), the V unfolds into a line,
//
//   sign * d = a (s - l),
//
// which is better conditioned (no split to choose) and rejects frames on the wrong side.
//
// Fit: for a fixed assignment of points to the sides of l both models are linear in (a, a l), so
// the exact least-squares V is found by trying every split between consecutive sorted s values
// (and beyond both ends), keeping solutions whose l lies in the split's interval, plus l pinned at
// each sample (O(n^2) for n points). Robustness: RANSAC over pairs of points (all pairs when there
// are at most ransac_iterations of them, else random pairs from `seed`), MSAC scoring, then least
// squares on the inliers, repeated until the inlier set settles. Deterministic for a given seed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace epiloc {

struct VFitOptions {
  // A point is an inlier if |d - model(s)| <= max_residual_fraction * median(d of all points)
  // + min_residual; > 0.
  double max_residual_fraction = 0.25;
  // Absolute floor of the inlier threshold, units of d (1/pixels for the epipolar distance),
  // >= 0; matters only when most points have d ~ 0.
  double min_residual = 0.0;
  // Fewest inliers for a valid fit, >= 2 (two points fix a line; 3 leave a check).
  int min_points = 3;
  // Fit the signed line where points carry a sign; false: every point is treated as unsigned.
  bool use_sign = true;
  // Random pairs drawn when the points have more pairs than this (else all pairs), >= 1.
  int ransac_iterations = 50;
  // Seed of the pair sampler.
  uint64_t seed = 0;

  void Check() const;
};

struct VFitPoint {
  double s_m = 0.0;  // along-route distance of the database frame, metres
  double d = 0.0;    // epipolar distance of the query frame against it, >= 0 (1/pixels)
  // Side of the database camera: +1 ahead of the query camera (s > l), -1 behind, 0 unknown.
  // Unknown points enter the signed fit with the side their s lies on (the V model).
  int sign = 0;
};

struct VFitResult {
  bool valid = false;
  // Why not valid: "too few points", "all points at one s", "too few inliers", "non-positive
  // slope", "extrapolation too far". The fields below are filled as far as the fit got.
  std::string failure;
  double l_m = 0.0;             // the query's along-route position, metres
  double slope = 0.0;           // a, units of d per metre
  double rms_residual = 0.0;    // RMS of d - model(s) over the inliers, units of d
  double rms_residual_m = 0.0;  // the same in metres along the route: rms_residual / slope
  int num_inliers = 0;
  std::vector<bool> inliers;  // per input point
};

// Fits eq. (3) to the points (any order). Invalid with a reason when: fewer than min_points points
// or inliers; all s equal; slope <= 0; or all inliers on one side of l with l farther than one
// sample spacing (median gap of the inliers' sorted s) outside [min s, max s]. Throws Error on
// bad input (d negative or not finite, s not finite, sign not in {-1, 0, 1}) or bad options.
VFitResult FitV(const std::vector<VFitPoint>& points, const VFitOptions& options);

}  // namespace epiloc
