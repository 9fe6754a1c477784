// The along-route position of a query frame from its epipolar pairs, with an honest uncertainty,
// and which pairs count as evidence (Kyutoku et al.'s V-fit, made robust).
//
// Model. For a database camera j at along-route distance s_j and the query at l (unknown), with
// the query's lateral offset Δy from the database's line, the baseline's direction has
// cot φ = v_z / |v_x| = (s_j - l) / |Δy| in the database camera's frame (which looks along the
// route): the signed cotangent u_j (PairResult::signed_cot; f d_j sign(q_z) with f the query's
// focal length and d = 1/|e_x| the paper's distance when the two cameras are parallel, but
// taken in the database camera's frame, so that the query's heading in a turn drops out) is
// linear in s,
//
//   u_j = A (s_j - l),  A = 1 / |Δy| > 0,
//
// the paper's V unfolded by the sign of q_z (vfit.h). Its noise follows from the direction's
// angular error σ_φ: du/dφ = 1 + u², so σ_u = σ_φ (1 + u²), and σ_φ of an essential matrix from
// N inliers with median parallax p (radians) is about σ_px / (f p √N): pairs beside the vehicle
// (small u) weigh most; far pairs (the epipole near the focus of expansion) and pairs with little
// parallax or support weigh little, whatever their d.
//
// Which pairs count (PairVerdict): valid ones (the essential matrix was found) with support of at
// least `min_relative_support` of the window's best pair, consistent with the robust line through
// the others (RANSAC over pairs of points, residuals in units of their own σ_u). A pair with a
// near-zero d where its neighbours say the vehicle is metres away (a degenerate epipole from a car
// driving ahead or repeated foliage) is an outlier of that line, not the nearest frame.
//
// Uncertainty: weighted least squares on the consistent pairs; l = x-intercept, its variance from
// the fit's covariance scaled by the larger of 1 and the residuals' own scale (the a-priori σ_φ
// is never trusted to be pessimistic), or the jackknife's over the fits leaving one pair out if
// larger (no single pair decides the position), plus `floor_sigma_m` (database positions).
#pragma once

#include <string>
#include <vector>

#include "epiloc/localize/pair_evaluator.h"

namespace epiloc {

struct EvidenceOptions {
  // A valid pair with fewer inliers than this share of the window's best pair is weak: a pair
  // of one query frame and database frames metres apart shares most of its view with its
  // neighbours, so a much lower support means the matches are mostly on something else (a car
  // ahead, repeated texture).
  double min_relative_support = 0.25;
  // Image noise of the matched features, pixels (the RANSAC threshold of the epipole is 1 px).
  double feature_sigma_px = 1.0;
  // Residuals beyond this many of their σ make a pair inconsistent with the line (RANSAC).
  double outlier_sigmas = 4.0;
  // Fewest consistent pairs for a measurement (two fix the line; a third checks it).
  int min_pairs = 3;
  // |Δy| = 1/A above this is no road geometry (the pairs' directions are noise): no measurement.
  double max_lateral_offset_m = 15.0;
  // Errors common to all pairs of a frame (calibration, rolling shutter, time offsets, an
  // essential matrix pulled by a dominant plane) are not in the model sigmas, which count
  // independent feature noise only; each measurement's sigma is its model sigma plus a floor in
  // quadrature. The floors come from the scenario suite as a whole (tools/bench_scenarios.sh,
  // one run of its 25 scenarios, tools/scenario_calibration.py on the per-frame errors): the
  // smallest round floor with 95 % of the measurements within 2 sigma of the truth. Epipolar:
  // 0.10 m (95.6 % of 4,269 measurements; 90.7 % on the real drive, where 0.03 m gave 51 %).
  // 6-DoF pose: 0.03 m (96.3 % of 4,442).
  double floor_sigma_m = 0.10;
  double pnp_floor_sigma_m = 0.03;

  void Check() const;
};

enum class PairVerdict {
  kUsed,          // evidence of the measurement
  kFailed,        // no essential matrix (PairResult::failure says why)
  kWeakSupport,   // fewer inliers than min_relative_support of the window's best
  kInconsistent,  // off the line through the other pairs (degenerate epipole, wrong side)
  kTurnedAway,    // the two cameras' headings differ by more than max_heading_deg
};
const char* PairVerdictName(PairVerdict verdict);

struct AlongTrackMeasurement {
  bool valid = false;
  std::string failure;            // why not valid
  double l_m = 0.0;               // the query's along-route position
  double sigma_m = 0.0;           // its standard deviation (the larger of the two below)
  double model_sigma_m = 0.0;     // from the fit's covariance alone (plus the floor)
  double lateral_offset_m = 0.0;  // |Δy| = 1/A
  double residual_scale = 0.0;    // RMS of the used pairs' residuals in units of their σ
  int num_used = 0;
  int num_ahead = 0, num_behind = 0;  // used pairs with the database camera ahead / behind
  std::vector<PairVerdict> verdicts;  // per input pair
};

// The measurement from the pairs of one query frame; `db_s_m[p.db_index]` is the along-route
// distance of each pair's database frame, `focal_px` the query camera's fx (of the undistorted
// image the pairs were evaluated on). A pair whose cameras' headings differ by more than
// `max_heading_deg` (PairResult::heading_deg) is no evidence (kTurnedAway): the model's cameras
// look along the route, and the localizer passes half the query camera's horizontal field of
// view, beyond which the two share less than half their views (a car turning into the street,
// whose few matches a wrong essential matrix fits as well as the right one). Deterministic.
AlongTrackMeasurement MeasureAlongTrack(const std::vector<PairResult>& pairs,
                                        const std::vector<double>& db_s_m,
                                        double focal_px,
                                        const EvidenceOptions& options,
                                        double max_heading_deg = 180.0);

}  // namespace epiloc
