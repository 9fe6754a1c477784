// The Localizer's state, shared by its translation units (tracking, result rows).
#pragma once

#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "epiloc/camera/undistorter.h"
#include "epiloc/db/database.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/route.h"
#include "epiloc/localize/localizer.h"
#include "epiloc/localize/track_filter.h"
#include "epiloc/retrieval/global_descriptor.h"

namespace epiloc {

// What the offline alignments need of one tracked frame.
struct RecordedFrame {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  bool off_route = false;
  int nearest = -1;
  std::vector<PairResult> valid_pairs;  // without point matches
};

// DTW costs of a row of evaluated pairs: (database index, cost in [0, 1]) sorted by index.
std::vector<std::pair<int, double>> RowCosts(const std::vector<PairResult>& pairs);

struct Localizer::Impl {
  Impl(const std::string& db_path, const Camera& camera, const LocalizeOptions& options);

  // Track's steps.
  std::vector<PairResult> Evaluate(const PreparedFrame& query, const std::vector<int>& indices);
  // A (re)initialisation: candidates from retrieval / the GNSS window, then the window around
  // the best-supported one (`reinitialised` then true).
  std::vector<PairResult> Initialise(const PreparedFrame& query,
                                     const std::optional<RouteProjection>& gnss,
                                     bool* reinitialised);
  std::vector<int> Window(double from_s_m, double to_s_m) const;
  // The 6-DoF refinement around `s_reference_m` (PnP, then search by projection).
  PoseRefinement Refine(const PreparedFrame& query,
                        double s_reference_m,
                        const std::vector<PairResult>& pairs);
  // Fuses the frame's measurements into the track (see Track).
  void Fuse(double timestamp_s, FrameEstimate* estimate);

  int num_db_frames() const;
  // Sub-frame position around database frame j from the valid pairs (V-fit, or the bracketing
  // sign change, or s_j).
  double SubFramePosition(const std::vector<PairResult>& pairs, int j, VFitResult* fit) const;

  std::string db_path;
  LocalizeOptions options;  // with the windows widened to the survey's spacing (see constructor)
  Database db;
  EnuFrame enu;
  Route route;
  Undistorter undistorter;
  std::vector<DbFrame> db_frames;  // route order (by s)
  std::vector<double> db_s;
  double min_window_spacing_m = 0.0;
  // Epipolar pairs whose cameras' headings differ by more than this are no evidence: half the
  // query camera's horizontal field of view (the narrower side of the principal point).
  double max_pair_heading_deg = 180.0;
  bool refine = false;
  std::unique_ptr<PairEvaluator> evaluator;
  std::optional<GlobalDescriptorModel> retrieval_model;
  GlobalIndex retrieval_index;
  std::unordered_map<int64_t, int> db_index_of_image;

  // The current frame's matching and geometry time (Evaluate adds to it; Track resets it).
  double match_seconds = 0.0, geometry_seconds = 0.0, window_seconds = 0.0;

  // Tracking state: the filter is initialised while the vehicle is tracked.
  AlongTrackFilter filter;
  // Time of the last tracked frame and the interval before it (Maintain's prefetch), seconds.
  std::optional<double> last_timestamp_s;
  double frame_interval_s = 0.0;
  int misses = 0;  // consecutive frames without an accepted measurement
  // The track has been confirmed since its (re)initialisation: by two agreeing measurements of
  // the first frame, or by a later frame's measurement passing the gate. Until then its frames
  // are not reported ok: one measurement alone (a degenerate epipole, a car still in the turn
  // into the street) must not place the vehicle.
  bool confirmed = false;
  // The best measurement of the last frame, when the track refused all of that frame's
  // measurements and each was better supported than the track (smaller sigma). A second such
  // frame whose measurement agrees with it replaces the track (see Fuse).
  struct Refused {
    double t, s_m, sigma_m, gate_sigma_m;
  };
  std::optional<Refused> refused;

  int64_t num_pairs = 0;
  int num_reinitialisations = 0;
  std::vector<RecordedFrame> record;  // with options.record_offline
};

}  // namespace epiloc
