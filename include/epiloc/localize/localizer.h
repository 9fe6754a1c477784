// Localizing a vehicle along a surveyed route, frame by frame (Kyutoku et al., "Epipolar
// geometry-based ego-localization using an in-vehicle monocular camera"), made robust and causal:
//   1. SIFT on each undistorted query frame (Prepare: may run ahead on other threads);
//   2. candidate database frames: around the GNSS prior (or by image retrieval without GNSS or
//      when lost) to initialise, then a window around the tracked position (Track);
//   3. epipolar distance d = 1/|e_x| to each candidate (PairEvaluator);
//   4. causal DTW over the evaluated costs (online) and the V-fit d = a|s - l| around its match
//      for a sub-frame position l along the route;
//   5. with a triangulated survey, a metric 6-DoF pose by PnP against its 3-D points (`pnp`).
// The offline alignments of the paper (DTW with free and with fixed ends) run once over what the
// tracker recorded (OfflineRows), after the last frame.
//
// A Localizer holds one route database and the state of one vehicle; memory is bounded over an
// endless stream when `record_offline` is off (with it, a few hundred bytes per frame are kept for
// the offline alignments).
//
// Example (see also examples/localize_drive.cc):
//   epiloc::Localizer localizer("route.sqlite", camera, epiloc::LocalizeOptions());
//   for (;;) {
//     epiloc::QueryFrame frame{number, timestamp_s, image, gnss_fix};
//     const epiloc::FrameEstimate estimate = localizer.Track(frame);
//     if (estimate.status == epiloc::TrackStatus::kOk) use(estimate.position, estimate.s_m);
//   }
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/core/types.h"
#include "epiloc/feature/sift.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/route.h"
#include "epiloc/io/result.h"
#include "epiloc/localize/dtw.h"
#include "epiloc/localize/evidence.h"
#include "epiloc/localize/pair_evaluator.h"
#include "epiloc/localize/pose_refiner.h"
#include "epiloc/localize/track_filter.h"
#include "epiloc/localize/vfit.h"

namespace epiloc {

struct LocalizeOptions {
  enum class Mode { kFixed, kFree, kOnline };
  Mode mode = Mode::kOnline;
  // Write every method (gps, nearest, dtw_fixed, fit_fixed, dtw_free, fit_free, online), not
  // only the chosen mode's.
  bool all_methods = false;
  // Use the frames' GNSS fixes as a prior (off: retrieval places the vehicle on the route).
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
  // Consecutive frames without an accepted measurement after which the track is lost (and
  // re-initialised from retrieval / the GNSS prior).
  int lost_after_frames = 3;
  // A frame whose tracked position has a larger standard deviation is reported lost, not placed:
  // a position that uncertain is no longer the few decimetres a user relies on.
  double max_sigma_m = 0.5;
  // A GPS prior farther than this from the route marks the frame off the route (not snapped).
  double off_route_m = 30.0;
  // A track farther than this beyond the first or last database camera is off the route: there
  // every pair has the vehicle on the same side, and the along-track line fitted to them is
  // extrapolated, its error growing with the distance. Two metres is one to two survey spacings
  // at the usual 1-1.5 m, where the extrapolation is still within the tracking window.
  double route_end_margin_m = 2.0;
  // One-sigma error of the survey positions themselves as they reach the database, added in
  // quadrature to every reported sigma (not to the measurements: it is common to neighbouring
  // frames and does not average out). An RTK/INS survey: 1-2 cm of RTK, plus the camera-to-GNSS
  // time offset and lever arm (a 3 ms offset is 3 cm at 10 m/s). Set it to the survey's own
  // figure (e.g. 0 for exact synthetic positions, metres for a GNSS-only survey).
  double survey_sigma_m = 0.05;
  // One-sigma horizontal error of a 6-DoF pose per metre of the query camera's offset from the
  // survey's line (the pose's cross-track distance), added in quadrature to the reported
  // horizontal sigma (not to the measurements). A survey map is exact only where it was seen
  // from: its points come from features whose 3-D position depends on the viewpoint (foliage,
  // occlusion edges, blobs over depth steps), triangulated along the survey's own line. Measured
  // on the shared KITTI drive, both ways round (a camera-1 query on a camera-0 map and a camera-0
  // query on a camera-1 map, 0.54 m apart, every frame, OXTS positions fused with the velocity):
  // the pose is pulled toward the map's line by 2.6-2.8 cm, an RMS of 0.055 and 0.059 per metre
  // of offset (0.05 rounded down). With the raw OXTS positions it was 0.21: their squeezed steps
  // in the open square put the map's points 10 % short along the survey's rays.
  double viewpoint_sigma_ratio = 0.05;
  // Working resolution: query images are reduced (one remap with the undistortion) until their
  // focal length is at most this times the database camera's; 0 keeps the query's own. A query
  // finer than the survey adds pixels, not matches: the survey holds no features finer than its
  // own pixels, and SIFT's scale space matches a feature seen larger or smaller from another
  // viewpoint (another lane, a few metres along) at another octave. 1 = the survey's pixel scale;
  // the time of extraction grows with the square of the ratio.
  double max_focal_ratio = 1.0;
  // Strongest query features used.
  int max_query_features = 2000;
  // Live input (LocalizeStream): a frame whose rows would come this many seconds or more after
  // its arrival, with a newer frame already waiting, is skipped (rows with status skipped): a
  // position that late is worth less than the current one, and the tracker catches up instead
  // of queueing every later frame behind a slow one (the first frame, a re-initialisation).
  // 0 tracks every frame (recorded drives; offline rows then cover every frame).
  double max_latency_s = 0.0;
  // Threads for pair evaluation inside Track (0 = one per core). Extraction ahead of the tracker
  // is the caller's (LocalizeStream uses the same number).
  int num_threads = 0;
  // Keep what the offline alignments need per frame (OfflineRows). Off: memory stays flat over an
  // endless stream. Switched on by Localize/LocalizeStream when mode or all_methods asks for them.
  bool record_offline = false;
  // FrameEstimate::pairs carries every evaluated pair (for --diagnostics).
  bool diagnostics = false;
  // Query extraction; by default without the upsampled octave (about 3x faster; the database
  // features too fine to match are then skipped, PairOptions::min_db_feature_angle_rad).
  SiftOptions sift = QuerySiftDefaults();
  PairOptions pairs;
  // Which pairs count and the epipolar position measurement (online).
  EvidenceOptions evidence;
  // The tracked position: motion model, speed limits, gating (online).
  TrackFilterOptions filter;
  // The paper's offline methods (free, fixed): DTW and V-fit.
  DtwOptions dtw;
  VFitOptions vfit;
  // 6-DoF refinement against the survey's 3-D points (`pnp` rows), when the database has them.
  RefineOptions refine;

  void Check() const;
  static SiftOptions QuerySiftDefaults();
  // Whether the options ask for the offline (free / fixed) rows.
  bool WantsOffline() const { return all_methods || mode != Mode::kOnline; }
};

std::string ModeName(LocalizeOptions::Mode mode);
LocalizeOptions::Mode ParseMode(const std::string& name);

// Where a frame's time went, per stage (wall-clock seconds of the thread that ran the stage;
// matching and geometry use several threads inside, so with more than one thread these are not
// CPU times). `epiloc localize` prints them averaged per frame; run it with --threads 1 for a
// profile whose stages add up to the CPU time per frame.
struct StageSeconds {
  double read = 0.0;       // image read and decoded by the frame source
  double undistort = 0.0;  // grey conversion, undistortion and reduction to the working size
  double sift = 0.0;       // SIFT detection and description
  double retrieval = 0.0;  // retrieval descriptor (and the query's index, pair-by-pair matching)
  double window = 0.0;     // database frames loaded into the window's index, index updated
  double match = 0.0;      // descriptor matching against the window's database frames
  double geometry = 0.0;   // epipolar geometry (RANSAC) of each pair
  double refine = 0.0;     // 6-DoF pose by PnP against the survey's points
  double other = 0.0;      // the rest of Track: evidence, filter, windows, rows

  StageSeconds& operator+=(const StageSeconds& o);
  double Extraction() const { return undistort + sift + retrieval; }
};

// One camera frame as it arrives.
struct QueryFrame {
  frame_t frame = kInvalidFrame;  // the caller's frame number (result rows carry it)
  double timestamp_s = 0.0;       // same clock as the GNSS fixes (UNIX time for real data)
  // 8-bit grey or BGR image as the camera delivers it (distorted, the calibration's size).
  cv::Mat image;
  std::optional<Geodetic> gnss;  // GNSS fix at timestamp_s, when there is one
  double arrival_s = 0.0;        // when the frame became available (steady clock, for latency)
  double read_seconds = 0.0;     // reading and decoding it (frame sources fill it in)
  std::string where;  // for messages: "<frames.csv>:<line>", "<video> frame <index>" or ""
};

// A frame after feature extraction (Localizer::Prepare), ready for Track.
struct PreparedFrame {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  std::optional<Geodetic> gnss;
  double arrival_s = 0.0;
  FeatureSet features;                     // of the undistorted frame, strongest first
  Eigen::VectorXf global;                  // retrieval descriptor (empty without an index)
  std::shared_ptr<DescriptorIndex> index;  // query index (pair-by-pair matching only)
  double extraction_seconds = 0.0;
  StageSeconds stages;  // read, undistort, sift, retrieval
  std::string where;  // QueryFrame::where
};

// kSkipped: not tracked at all (LocalizeStream skipped the frame: it was late and a newer one
// was waiting, LocalizeOptions::max_latency_s).
enum class TrackStatus { kOk, kLost, kOffRoute, kSkipped };
const char* TrackStatusName(TrackStatus status);

// What Track reports for one frame, at once.
struct FrameEstimate {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  TrackStatus status = TrackStatus::kLost;
  // The online estimate (status kOk): the tracked along-route distance (epipolar and 6-DoF
  // evidence fused under the motion model), its standard deviation, the camera centre on the
  // route.
  double s_m = 0.0;
  double sigma_along_m = 0.0;
  Geodetic position;
  int db_index = -1;                 // the database frame nearest to s_m (route order)
  frame_t db_frame = kInvalidFrame;  // its frame number
  int num_inliers = -1;              // inliers of the pair with that frame (-1: none)
  AlongTrackMeasurement epipolar;    // the frame's epipolar measurement and pair verdicts
  double pnp_sigma_m = 0.0;          // along-track sigma of the 6-DoF measurement (when refined)
  bool epipolar_accepted = false;    // it moved the track
  bool pnp_accepted = false;         // the 6-DoF pose's position moved the track
  // The two disagreed: the better-supported one (consistent with the track) won.
  bool conflict = false;
  std::string note;            // why evidence was refused, why the frame is lost, ...
  bool reinitialised = false;  // the window came from a (re)initialisation
  int window_extensions = 0;   // times the window was extended to bracket the vehicle
  // The GNSS prior of the frame and its projection onto the route.
  std::optional<Geodetic> gnss;
  std::optional<RouteProjection> gnss_on_route;
  int nearest_db_index = -1;  // the valid pair of smallest d (the paper's "nearest")
  int nearest_inliers = -1;   // its inliers
  // The 6-DoF refinement (set for localized frames when the database has structure).
  std::optional<PoseRefinement> refined;
  // Every evaluated pair (with options.diagnostics; point matches dropped).
  std::vector<PairResult> pairs;
  int num_pairs = 0;  // pairs evaluated for this frame
  double extraction_seconds = 0.0;
  double tracking_seconds = 0.0;
  StageSeconds stages;  // every stage, Prepare's and Track's
  // From the frame's arrival (QueryFrame::arrival_s) to the estimate, when a stream (LocalizeStream)
  // tracked it: extraction, tracking and every wait between (0 when tracked directly).
  double latency_seconds = 0.0;
};

class Localizer {
 public:
  // Opens the route database (read-only) for a query camera with calibration `query_camera` (as
  // its frames are delivered: distortion allowed). Throws Error for a database without frames,
  // invalid options, or --no-gps with a database without retrieval index.
  Localizer(const std::string& db_path, const Camera& query_camera, const LocalizeOptions& options);
  ~Localizer();
  Localizer(const Localizer&) = delete;
  Localizer& operator=(const Localizer&) = delete;

  // Undistortion, SIFT and the retrieval descriptor of a frame. Thread-safe: may run ahead of
  // Track on other threads. Throws Error if the image does not have the calibration's size.
  PreparedFrame Prepare(const QueryFrame& frame) const;
  // Tracks one frame (frames in time order) and returns its estimate.
  FrameEstimate Track(const PreparedFrame& frame);
  FrameEstimate Track(const QueryFrame& frame) { return Track(Prepare(frame)); }
  // Upkeep Track left due (a rebuild of the window's descriptor index once incremental updates
  // have unbalanced it): call it after a frame's rows are out, while waiting for the next frame,
  // to keep it off that frame's latency. Track does it first itself when it is still due; the
  // results do not depend on whether or when it is called.
  void Maintain();

  // Result rows of a tracked frame (gps and nearest with all_methods, online when the mode or
  // all_methods asks for it, pnp when refining), in that order.
  std::vector<ResultRow> Rows(const FrameEstimate& estimate) const;
  // Rows of the offline alignments over every frame tracked so far (dtw_fixed, fit_fixed,
  // dtw_free, fit_free as the options ask); needs options.record_offline.
  std::vector<ResultRow> OfflineRows() const;
  // The extra columns of the rows (after the required ones and qw..qz).
  static const std::vector<std::string>& ExtraColumns();
  // Whether pnp rows (with orientations) are written: the database has triangulated points and
  // the refinement is enabled.
  bool refining() const;

  const LocalizeOptions& options() const;
  const Camera& query_camera() const;  // undistorted pinhole camera the features refer to
  int num_db_frames() const;
  frame_t db_frame_number(int db_index) const;
  double db_s_m(int db_index) const;
  const Route& route() const;
  int64_t num_pairs() const;
  int num_reinitialisations() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace epiloc
