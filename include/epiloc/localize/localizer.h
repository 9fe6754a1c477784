// Localizing a drive along a surveyed route (Kyutoku et al., "Epipolar geometry-based
// ego-localization using an in-vehicle monocular camera"), made robust and causal:
//   1. SIFT on each undistorted query frame;
//   2. candidate database frames: around the GPS prior (or by image retrieval without GPS or when
//      lost) to initialise, then a window around the tracked position;
//   3. epipolar distance d = 1/|e_x| to each candidate (PairEvaluator);
//   4. DTW over the sparse cost matrix: online (causal), free (start fixed, end free) and fixed
//      (both ends fixed);
//   5. sub-frame position from the V-fit d = a|s - l| around the DTW match, interpolated along
//      the database route.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "epiloc/core/progress.h"
#include "epiloc/feature/sift.h"
#include "epiloc/io/result.h"
#include "epiloc/localize/dtw.h"
#include "epiloc/localize/pair_evaluator.h"
#include "epiloc/localize/pose_refiner.h"
#include "epiloc/localize/vfit.h"

namespace epiloc {

struct LocalizeOptions {
  enum class Mode { kFixed, kFree, kOnline };
  Mode mode = Mode::kOnline;
  // Write every method (gps, nearest, dtw_fixed, fit_fixed, dtw_free, fit_free, online), not
  // only the chosen mode's.
  bool all_methods = false;
  // Use the drive's GNSS as a prior (off: retrieval places the drive on the route).
  bool use_gps = true;
  // Half-width of the along-route window searched around the GPS prior when (re)initialising.
  double gps_window_m = 30.0;
  // Database frames evaluated at (re)initialisation: the best retrieval/prior candidates.
  int init_candidates = 8;
  // Half-width of the window of database frames evaluated around the predicted position (at
  // least 2.5 database frame spacings; the window is extended when it does not bracket the
  // vehicle).
  double track_window_m = 2.0;
  // A denser survey is thinned to about this many frames per tracking window (frames at least
  // 2 * track_window_m / max_window_frames apart), so its frame rate does not set the speed.
  int max_window_frames = 8;
  // The V-fit uses database frames within this distance of the DTW match (at least 2.5 spacings).
  double fit_window_m = 2.6;
  // Consecutive frames without a valid pair after which the track is lost (re-initialised).
  int lost_after_frames = 3;
  // A GPS prior farther than this from the route marks the frame off the route (not snapped).
  double off_route_m = 30.0;
  // Strongest query features used.
  int max_query_features = 2000;
  // Threads for feature extraction and pair evaluation (0 = one per core).
  int num_threads = 0;
  // Query extraction; by default without the upsampled octave (about 3x faster; the database
  // features too fine to match are then skipped, PairOptions::min_db_feature_angle_rad).
  SiftOptions sift = QuerySiftDefaults();
  PairOptions pairs;
  DtwOptions dtw;
  VFitOptions vfit;
  // 6-DoF refinement against the survey's 3-D points (`pnp` rows), when the database has them.
  RefineOptions refine;

  void Check() const;
  static SiftOptions QuerySiftDefaults();
};

std::string ModeName(LocalizeOptions::Mode mode);
LocalizeOptions::Mode ParseMode(const std::string& name);

// Per-frame diagnostics (--diagnostics): what the localizer saw.
struct FrameDiagnostics {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  std::optional<double> gps_s_m;
  std::vector<PairResult> pairs;
  int online_db_index = -1;
  VFitResult online_fit;
  bool reinitialised = false;
  int window_extensions = 0;  // times the window was extended to bracket the vehicle
  double seconds = 0.0;       // processing time of the frame (extraction excluded when pipelined)
};

struct LocalizeRun {
  ResultTable results;
  std::vector<frame_t> db_frame_numbers;  // per database index (route order)
  std::vector<double> db_s_m;             // per database index
  std::vector<FrameDiagnostics> diagnostics;
  int num_frames = 0;
  int num_localized_online = 0;
  int num_reinitialisations = 0;
  double seconds = 0.0;
  double frames_per_second = 0.0;
  int64_t num_pairs = 0;
  bool refined = false;         // pnp rows were written (the database has structure)
  int num_refined_ok = 0;       // frames with an accepted PnP pose
  int num_refine_thin = 0;      // fell back to the epipolar estimate: too little structure
  int num_refine_rejected = 0;  // fell back: the PnP pose disagreed with the sequence
};

// Localizes every frame of the drive in `drive_dir` against the database. Throws Error for bad
// input; frames that cannot be localized are rows with status lost / off_route.
LocalizeRun Localize(const std::string& db_path,
                     const std::string& drive_dir,
                     const LocalizeOptions& options,
                     const ProgressCallback& progress = nullptr);

// Writes the per-frame diagnostics as CSV (one row per evaluated pair).
void WriteDiagnosticsCsv(const LocalizeRun& run, const std::string& path);

}  // namespace epiloc
