// A residual radial distortion of the camera estimated from the LiDAR map (`epiloc
// calibrate-radial`): the term of the camera's radial model (k1 or k2) at which the monocular VO
// keeps its scale along the drive, as the map measures it.
//
// Why: a radial calibration error does not show in the VO's own residuals (its scale drift
// absorbs it) but makes the VO's scale change steadily along the drive (README, "What the drift
// responds to": the shared KITTI drive's rectified images carry one that costs 14 % of scale over
// 60 m; a KITTI-like synthetic camera keeps its scale within 1 % over 120 m with the right
// calibration and changes it by 8-11 % with k1 off by 0.02). Structure anchors measure the VO's
// scale against the map at every anchor (ScaleTrendOfAnchors), so the trend of that scale along
// the road is a function of the term, zero at the right one.
//
// How: the drive's VO is run with the term as calibrated, the drive anchored from its structure
// (as `epiloc anchor --structure auto` does), the scale trend taken; then with the term moved by
// `first_step` against the trend's sign (a larger k1 or k2 raises the trend, on the synthetic
// camera and on KITTI alike), and from there by the secant through the last two runs, each step at
// most `max_step`, until the trend is within `tolerance_percent_per_100m` or `max_runs` runs are
// spent. The result is the run with the smallest trend. One term only: k1 and k2 remove a steady
// drift alike (the scale trend is one number per run); k1 is the default, the one-parameter
// radial model of most self-calibration (COLMAP's SIMPLE_RADIAL).
//
// Limits: a VO whose scale drifts for other reasons (a short drive, a long stop, a scene of one
// depth) gives a trend the term would wrongly take up; the drive should cover some tens of metres
// with ok anchors at both ends (min_distance_m), and the term's change is bounded (max_change).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/anchor/anchor.h"
#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/camera/camera.h"
#include "epiloc/core/progress.h"
#include "epiloc/vo/visual_odometry.h"

namespace epiloc {

struct RadialCalibrationOptions {
  enum class Term { kK1, kK2 };
  Term term = Term::kK1;
  double first_step = 0.01;   // the second run's term minus the first's (sign: against the trend)
  double max_step = 0.03;     // at most this between two runs' terms
  double max_change = 0.06;   // the term moves at most this far from the drive's calibration
  double tolerance_percent_per_100m = 2.0;  // a trend within this is "no trend" (converged)
  int max_runs = 5;
  double min_distance_m = 30.0;  // between the first and the last ok anchor of a run
  VoOptions vo;
  StructureAnchorOptions structure;
  int sift_threads = 2;  // the SIFT structure's feature extraction (when the VO's points do not
                         // fix the anchors along the road)

  // Throws Error naming the first invalid field.
  void Check() const;
};

// The radial term's index in Camera::distortion (k1: 0, k2: 1) and its name.
int RadialTermIndex(RadialCalibrationOptions::Term term);
const char* RadialTermName(RadialCalibrationOptions::Term term);

// One run: the term, what its anchors measured.
struct RadialCalibrationRun {
  double term = 0.0;
  std::optional<VoScaleTrend> trend;  // none: too few ok anchors or too short (message says)
  int ok_anchors = 0;
  int anchors = 0;
  double median_residual_m = 0.0;  // the ok anchors' registration residual (RMS), median
  double seconds = 0.0;            // VO and anchoring
  std::string message;             // why a run has no usable trend
};

struct RadialCalibrationResult {
  bool converged = false;  // a run's trend within the tolerance
  double term = 0.0;       // the best run's term (the drive's own when no run measured a trend)
  Camera camera;           // the drive's camera with that term
  int best_run = -1;       // index into runs; -1 when no run measured a trend
  std::vector<RadialCalibrationRun> runs;
  std::string message;     // why not converged
  VoResult vo;             // CalibrateRadialTerm: the best run's VO (empty when none)
};

// The root search alone, on any measurement of the trend (`measure(term)`, which returns the run
// with its trend or without one): the secant described above. Stops without converging when a run
// has no usable trend, when two runs measure the same trend, or after max_runs. Used by
// CalibrateRadialTerm; exposed for tests.
RadialCalibrationResult SearchRadialTerm(
    double calibrated_term,
    const RadialCalibrationOptions& options,
    const std::function<RadialCalibrationRun(double term)>& measure);

// Runs the search on a drive (inputs.drive_dir: its frames, GNSS and camera; inputs.cloud_path
// and map_origin: the map; inputs.frames / every: the anchored frames; inputs.vo_path unused).
// Each run's drive (the camera with the run's term) is written to `work_dir`/run_N, which the
// SIFT structure reads its calibration from. `on_run` (may be null) gets each run as it is done.
// The result keeps the best run's VO. Throws Error as RunVisualOdometry and
// AnchorDriveByStructure do.
RadialCalibrationResult CalibrateRadialTerm(
    const AnchorInputs& inputs,
    const RadialCalibrationOptions& options,
    const std::string& work_dir,
    const std::function<void(const RadialCalibrationRun&)>& on_run = nullptr,
    const ProgressCallback& progress = nullptr);

}  // namespace epiloc
