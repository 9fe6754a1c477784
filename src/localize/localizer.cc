#include "epiloc/localize/localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"
#include "epiloc/survey/retrieval_index.h"
#include "localizer_internal.h"

namespace epiloc {
namespace {

using Clock = std::chrono::steady_clock;

// Times the evaluated window may be extended in one frame when it does not bracket the vehicle.
constexpr int kMaxWindowExtensions = 3;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// Database frames whose s lies in [from, to] (frames sorted by s).
std::vector<int> FramesBetween(const std::vector<double>& db_s, double from, double to) {
  const auto lo = std::lower_bound(db_s.begin(), db_s.end(), from);
  const auto hi = std::upper_bound(db_s.begin(), db_s.end(), to);
  std::vector<int> out;
  for (auto it = lo; it < hi; ++it) out.push_back(static_cast<int>(it - db_s.begin()));
  return out;
}

// `frames` (ascending s) thinned so that kept frames are at least `min_spacing_m` apart along
// the route (greedy from the first); all of them when min_spacing_m <= 0.
std::vector<int> Thinned(const std::vector<int>& frames,
                         const std::vector<double>& db_s,
                         double min_spacing_m) {
  if (min_spacing_m <= 0 || frames.size() < 2) return frames;
  std::vector<int> kept;
  for (const int j : frames) {
    if (kept.empty() || db_s[j] - db_s[kept.back()] >= min_spacing_m) kept.push_back(j);
  }
  return kept;
}

// The valid pair of smallest d (ties: more inliers); -1 if none.
int NearestPair(const std::vector<PairResult>& pairs) {
  int best = -1;
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!pairs[k].valid) continue;
    if (best < 0 || pairs[k].distance < pairs[best].distance) best = static_cast<int>(k);
  }
  return best < 0 ? -1 : pairs[best].db_index;
}

// The database index of the valid pair with the most inliers, or -1.
int BestSupportedPair(const std::vector<PairResult>& pairs) {
  int best = -1;
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (pairs[k].valid && (best < 0 || pairs[k].num_inliers > pairs[best].num_inliers)) {
      best = static_cast<int>(k);
    }
  }
  return best < 0 ? -1 : pairs[best].db_index;
}

// How many valid pairs place their database camera ahead of the vehicle (q_z > 0) and behind it.
struct Sides {
  int ahead = 0, behind = 0;
};
Sides CountSides(const std::vector<PairResult>& pairs) {
  Sides sides;
  for (const PairResult& p : pairs) {
    if (p.valid) (p.signed_distance > 0 ? sides.ahead : sides.behind) += 1;
  }
  return sides;
}

// Which side of the evaluated window the query lies on, from the signs of q_z: +1 if every valid
// database camera is ahead (the query is behind the window), -1 if every one is behind, 0 if the
// window brackets the query (or there is too little evidence to say).
int OutsideWindow(const std::vector<PairResult>& pairs) {
  const Sides sides = CountSides(pairs);
  if (sides.ahead + sides.behind < 3) return 0;
  if (sides.behind == 0) return +1;
  if (sides.ahead == 0) return -1;
  return 0;
}

// Whether the valid pairs place the vehicle between database cameras: at least one ahead of it
// and one behind it, three or more in all.
bool Brackets(const std::vector<PairResult>& pairs) {
  const Sides sides = CountSides(pairs);
  return sides.ahead > 0 && sides.behind > 0 && sides.ahead + sides.behind >= 3;
}

}  // namespace

// DTW costs of a row: d relative to twice the row's median valid d, capped at 1 (the cost of a
// missing cell), so rows of different lateral offsets weigh alike and one wild d (an epipole
// near the principal point from a bad model) cannot flatten the rest; failed pairs are missing.
std::vector<std::pair<int, double>> RowCosts(const std::vector<PairResult>& pairs) {
  std::vector<double> d;
  for (const PairResult& p : pairs) {
    if (p.valid) d.push_back(p.distance);
  }
  std::vector<std::pair<int, double>> row;
  if (d.empty()) return row;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  const double scale = 2.0 * d[d.size() / 2];
  for (const PairResult& p : pairs) {
    if (!p.valid) continue;
    row.emplace_back(p.db_index, scale > 0 ? std::min(1.0, p.distance / scale) : 0.0);
  }
  std::sort(row.begin(), row.end());
  return row;
}

std::string ModeName(LocalizeOptions::Mode mode) {
  switch (mode) {
    case LocalizeOptions::Mode::kFixed:
      return "fixed";
    case LocalizeOptions::Mode::kFree:
      return "free";
    case LocalizeOptions::Mode::kOnline:
      return "online";
  }
  return "?";
}

LocalizeOptions::Mode ParseMode(const std::string& name) {
  if (name == "fixed") return LocalizeOptions::Mode::kFixed;
  if (name == "free") return LocalizeOptions::Mode::kFree;
  if (name == "online") return LocalizeOptions::Mode::kOnline;
  Throw("--mode '{}': expected fixed, free or online", name);
}

const char* TrackStatusName(TrackStatus status) {
  switch (status) {
    case TrackStatus::kOk:
      return "ok";
    case TrackStatus::kLost:
      return "lost";
    case TrackStatus::kOffRoute:
      return "off_route";
    case TrackStatus::kSkipped:
      return "skipped";
  }
  return "?";
}

SiftOptions LocalizeOptions::QuerySiftDefaults() {
  SiftOptions sift;
  sift.upsampled_octave = false;
  return sift;
}

void LocalizeOptions::Check() const {
  EPILOC_CHECK(gps_window_m > 0, "localize: gps_window_m must be > 0");
  EPILOC_CHECK(init_candidates >= 2, "localize: init_candidates must be >= 2");
  EPILOC_CHECK(track_window_m > 0, "localize: track_window_m must be > 0");
  EPILOC_CHECK(max_window_frames >= 4, "localize: max_window_frames must be >= 4, got {}",
               max_window_frames);
  EPILOC_CHECK(fit_window_m > 0, "localize: fit_window_m must be > 0");
  EPILOC_CHECK(lost_after_frames >= 1, "localize: lost_after_frames must be >= 1");
  EPILOC_CHECK(max_query_features >= 16, "localize: max_query_features must be >= 16");
  EPILOC_CHECK(num_threads >= 0, "localize: num_threads must be >= 0");
  sift.Check();
  pairs.Check();
  dtw.Check();
  evidence.Check();
  filter.Check();
  vfit.Check();
  refine.Check();
  EPILOC_CHECK(max_sigma_m > 0, "localize: max_sigma_m must be > 0");
  EPILOC_CHECK(off_route_m > 0, "localize: off_route_m must be > 0, got {}", off_route_m);
  EPILOC_CHECK(route_end_margin_m >= 0, "localize: route_end_margin_m must be >= 0");
  EPILOC_CHECK(max_focal_ratio >= 0, "localize: max_focal_ratio must be >= 0");
  EPILOC_CHECK(std::isfinite(max_latency_s) && max_latency_s >= 0,
               "localize: max_latency_s must be >= 0");
  EPILOC_CHECK(survey_sigma_m >= 0 && std::isfinite(survey_sigma_m),
               "localize: survey_sigma_m must be finite and >= 0");
  EPILOC_CHECK(viewpoint_sigma_ratio >= 0 && std::isfinite(viewpoint_sigma_ratio),
               "localize: viewpoint_sigma_ratio must be finite and >= 0");
}

namespace {

Geodetic OriginOf(const Database& db, const std::string& path) {
  const std::optional<Geodetic> origin = db.EnuOrigin();
  EPILOC_CHECK(origin.has_value(), "{}: the database has no frames (no ENU origin)", path);
  return *origin;
}

// The database's route polyline; a degenerate one is reported as the database's ("route: needs at
// least two distinct positions" named no file).
Route RouteOf(const Database& db, const std::string& path) {
  try {
    return Route(db.ReadRoute());
  } catch (const Error& e) {
    Throw("{}: {}", path, e.what());
  }
}

// Appends one clause to a frame's note ("; "-separated).
void AddNote(std::string* note, const std::string& text) {
  if (!note->empty()) *note += "; ";
  *note += text;
}

// The working focal length of the query images: at most `ratio` times the finest database
// camera's (0: the query's own). Finer query pixels have no database features at their scale to
// match; they cost extraction time only.
double WorkingFocal(const Database& db, double ratio) {
  if (ratio <= 0) return 0.0;
  double focal = 0.0;
  for (const DbDrive& drive : db.ReadDrives()) {
    if (drive.camera_id == kInvalidCamera) continue;
    const Camera& camera = db.ReadCamera(drive.camera_id).camera;
    focal = std::max(focal, std::max(camera.fx, camera.fy));
  }
  return ratio * focal;
}

}  // namespace

Localizer::Impl::Impl(const std::string& path, const Camera& camera, const LocalizeOptions& opts)
    : db_path(path),
      options(opts),
      db(path, Database::Mode::kReadOnly),
      enu(OriginOf(db, path)),
      route(RouteOf(db, path)),
      undistorter(camera, WorkingFocal(db, opts.max_focal_ratio)),
      filter(opts.filter) {
  options.Check();
  db_frames = db.ReadFrames();
  EPILOC_CHECK(db_frames.size() >= 2, "{}: the database holds {} frames, at least 2 needed", path,
               db_frames.size());
  for (const DbDrive& drive : db.ReadDrives()) {
    if (!drive.complete) {
      spdlog::warn(
          "{}: survey drive '{}' is incomplete (its build was interrupted): frames beyond "
          "the last one built are reported off_route",
          path, drive.name);
    }
  }
  std::stable_sort(db_frames.begin(), db_frames.end(),
                   [](const DbFrame& a, const DbFrame& b) { return a.s_m < b.s_m; });
  const int num_db = static_cast<int>(db_frames.size());
  for (const DbFrame& f : db_frames) db_s.push_back(f.s_m);
  // Windows scale with the database's frame spacing, so a sparse survey still gives the V-fit
  // enough frames on both sides: at least 2.5 spacings, never less than the options say.
  std::vector<double> spacing;
  for (int j = 1; j < num_db; ++j) {
    if (db_s[j] > db_s[j - 1]) spacing.push_back(db_s[j] - db_s[j - 1]);
  }
  double median_spacing = 0.0;
  if (!spacing.empty()) {
    std::nth_element(spacing.begin(), spacing.begin() + spacing.size() / 2, spacing.end());
    median_spacing = spacing[spacing.size() / 2];
  }
  options.track_window_m = std::max(opts.track_window_m, 2.5 * median_spacing);
  options.fit_window_m = std::max(opts.fit_window_m, 2.5 * median_spacing);
  // A dense survey (a high frame rate, a slow survey vehicle) would put many frames into each
  // window; evaluating frames closer than this adds time, not accuracy.
  min_window_spacing_m = 2.0 * options.track_window_m / options.max_window_frames;
  if (options.num_threads == 0) {
    options.num_threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  }

  const Camera& query_camera = undistorter.undistorted_camera();
  max_pair_heading_deg =
      std::atan(std::min(query_camera.cx, query_camera.width - query_camera.cx) / query_camera.fx) *
      180.0 / M_PI;
  PairOptions pair_options = options.pairs;
  if (pair_options.min_db_feature_angle_rad == 0) {
    // Database features finer than 3/4 of the finest the query extraction detects cannot match
    // it (the margin allows for the scale change between the two viewpoints).
    pair_options.min_db_feature_angle_rad =
        0.75 * SmallestKeypointSizePx(options.sift, query_camera.width, query_camera.height) /
        query_camera.fx;
  }
  refine = options.refine.enabled && db.NumPoints() > 0;
  if (options.refine.enabled && !refine) {
    spdlog::warn("{}: no triangulated 3-D points (run epiloc triangulate); no 6-DoF refinement",
                 path);
  }
  pair_options.with_points = refine;
  // The window index's rebuilds wait for Maintain() (or the next frame): off the latency.
  pair_options.window.defer_rebuilds = true;
  evaluator = std::make_unique<PairEvaluator>(db, db_frames, pair_options);

  // Whole-route image retrieval places the vehicle without GPS and recovers a lost track.
  if (HasCurrentRetrievalIndex(db)) {
    retrieval_model.emplace();
    retrieval_index = LoadRetrievalIndex(db, &*retrieval_model);
    for (int j = 0; j < num_db; ++j) db_index_of_image[db_frames[j].image_id] = j;
  } else if (!options.use_gps) {
    Throw("{}: localizing without GPS needs the database's retrieval index (re-run build-db)",
          path);
  } else {
    spdlog::warn("{}: no retrieval index; a lost track re-initialises from GPS only", path);
  }
}

std::vector<int> Localizer::Impl::Window(double from_s_m, double to_s_m) const {
  return Thinned(FramesBetween(db_s, from_s_m, to_s_m), db_s, min_window_spacing_m);
}

std::vector<PairResult> Localizer::Impl::Evaluate(const PreparedFrame& query,
                                                  const std::vector<int>& indices) {
  const Camera& camera = undistorter.undistorted_camera();
  std::vector<PairResult> r;
  if (options.pairs.window_matching) {
    r = evaluator->EvaluateWindow(camera, query.features, indices, options.num_threads,
                                  &match_seconds, &geometry_seconds, &window_seconds);
  } else {
    // Pair by pair, matching and geometry interleave: all of it counts as matching.
    const auto start = Clock::now();
    r = evaluator->Evaluate(camera, query.features.keypoints, *query.index, indices,
                            options.num_threads);
    match_seconds += Seconds(start);
  }
  num_pairs += static_cast<int64_t>(r.size());
  return r;
}

std::vector<PairResult> Localizer::Impl::Initialise(const PreparedFrame& query,
                                                    const std::optional<RouteProjection>& gnss,
                                                    bool* reinitialised) {
  *reinitialised = false;
  const int num_db = static_cast<int>(db_frames.size());
  // A coarse sweep of the prior window, then the dense window around the best-supported frame.
  // Candidates: the best retrieval matches (inside the GPS window when there is one), or an even
  // sweep of the GPS window without a retrieval index.
  std::vector<int> sweep;
  if (retrieval_model && query.global.size() > 0) {
    const int wanted = options.init_candidates;
    const int searched = gnss ? std::min(num_db, 20 * wanted) : wanted;
    for (const auto& [image_id, score] : retrieval_index.Search(query.global, searched)) {
      const int j = db_index_of_image.at(image_id);
      if (gnss && std::abs(db_s[j] - gnss->s_m) > options.gps_window_m) continue;
      sweep.push_back(j);
      if (static_cast<int>(sweep.size()) >= wanted) break;
    }
  }
  if (sweep.empty() && gnss) {
    const std::vector<int> window =
        FramesBetween(db_s, gnss->s_m - options.gps_window_m, gnss->s_m + options.gps_window_m);
    const size_t step = std::max<size_t>(1, window.size() / (2 * options.init_candidates));
    for (size_t k = 0; k < window.size(); k += step) sweep.push_back(window[k]);
  }
  std::sort(sweep.begin(), sweep.end());
  const std::vector<PairResult> coarse = Evaluate(query, sweep);
  const int best = BestSupportedPair(coarse);
  if (best < 0) return coarse;
  const double s0 = db_s[best];
  ++num_reinitialisations;
  *reinitialised = true;
  return Evaluate(query, Window(s0 - options.track_window_m, s0 + options.track_window_m));
}

double Localizer::Impl::SubFramePosition(const std::vector<PairResult>& pairs,
                                         int j,
                                         VFitResult* fit_out) const {
  std::vector<VFitPoint> points;
  for (const PairResult& p : pairs) {
    if (!p.valid || std::abs(db_s[p.db_index] - db_s[j]) > options.fit_window_m) continue;
    VFitPoint point;
    point.s_m = db_s[p.db_index];
    point.d = p.distance;
    point.sign = p.signed_distance > 0 ? 1 : (p.signed_distance < 0 ? -1 : 0);
    points.push_back(point);
  }
  VFitResult fit;
  if (static_cast<int>(points.size()) >= options.vfit.min_points) fit = FitV(points, options.vfit);
  if (fit_out) *fit_out = fit;
  if (fit.valid && std::abs(fit.l_m - db_s[j]) <= options.fit_window_m) return fit.l_m;
  // Too few points for the fit (e.g. at a route end): the sign change between the two database
  // cameras that bracket the vehicle, interpolated linearly in d (eq. 3 with two points).
  std::sort(points.begin(), points.end(),
            [](const VFitPoint& a, const VFitPoint& b) { return a.s_m < b.s_m; });
  const VFitPoint* best_a = nullptr;
  const VFitPoint* best_b = nullptr;
  for (size_t k = 0; k + 1 < points.size(); ++k) {
    const VFitPoint& a = points[k];
    const VFitPoint& b = points[k + 1];
    if (a.sign < 0 && b.sign > 0 &&
        (!best_a || std::abs(0.5 * (a.s_m + b.s_m) - db_s[j]) <
                        std::abs(0.5 * (best_a->s_m + best_b->s_m) - db_s[j]))) {
      best_a = &a;
      best_b = &b;
    }
  }
  if (best_a) {
    const double w = best_a->d / (best_a->d + best_b->d);
    return best_a->s_m + w * (best_b->s_m - best_a->s_m);
  }
  return db_s[j];
}

PoseRefinement Localizer::Impl::Refine(const PreparedFrame& query,
                                       double s_reference_m,
                                       const std::vector<PairResult>& pairs) {
  const Camera& camera = undistorter.undistorted_camera();
  PoseRefinement refined =
      RefinePose(camera, query.features.keypoints, pairs, s_reference_m, route, options.refine);
  if (!options.refine.search_by_projection || refined.status != RefineStatus::kOk) return refined;
  // The local map: the points seen by the database frames from local_map_behind_m behind to
  // local_map_ahead_m ahead of the estimate (far points constrain the along-track position), the
  // evaluated window's first, then the others nearest first (a point keeps the descriptor of the
  // first frame that sees it: the view closest to the query's).
  const double s = refined.projection.s_m;
  std::vector<std::shared_ptr<const FrameMapPoints>> local_map;
  for (const PairResult& p : pairs) local_map.push_back(evaluator->MapPoints(p.db_index));
  std::vector<int> frames = FramesBetween(db_s, s - options.refine.local_map_behind_m,
                                          s + options.refine.local_map_ahead_m);
  std::stable_sort(frames.begin(), frames.end(),
                   [&](int a, int b) { return std::abs(db_s[a] - s) < std::abs(db_s[b] - s); });
  for (const int j : frames) local_map.push_back(evaluator->MapPoints(j));
  const std::vector<float> root_sift =
      ToRootSift(query.features.descriptors, query.features.size());
  return RefineByProjection(camera, query.features.keypoints, root_sift, local_map, refined,
                            s_reference_m, route, options.refine);
}

void Localizer::Impl::Fuse(double t, FrameEstimate* est) {
  // sigma_m weighs the measurement; gate_sigma_m (<= sigma_m) decides whether it agrees with
  // the track or the other measurement. Each sigma is the larger of the model's and the
  // jackknife's (6-DoF: errors shared by a region of the image; epipolar: one pair deciding the
  // line), and each is gated with the model's alone, so a measurement must agree with the track
  // even at the precision it claims. A weak one far off (a big jackknife sigma) is refused, not
  // taken in with a weight that barely moves the track and then reported.
  struct Measurement {
    double s_m, sigma_m, gate_sigma_m;
    bool* accepted;
    const char* name;
  };
  std::vector<Measurement> measurements;
  if (est->epipolar.valid) {
    measurements.push_back({est->epipolar.l_m, est->epipolar.sigma_m, est->epipolar.model_sigma_m,
                            &est->epipolar_accepted, "epipolar"});
  }
  if (est->refined && est->refined->status == RefineStatus::kOk) {
    const PoseRefinement& r = *est->refined;
    const double floor = options.evidence.pnp_floor_sigma_m;
    est->pnp_sigma_m = std::hypot(r.sigma_along_m, floor);
    measurements.push_back({r.projection.s_m, est->pnp_sigma_m,
                            std::hypot(r.sigma_along_model_m, floor), &est->pnp_accepted, "pnp"});
  }
  // The better-supported (smaller sigma) first: when the two disagree, the track takes it.
  std::sort(measurements.begin(), measurements.end(),
            [](const Measurement& a, const Measurement& b) { return a.sigma_m < b.sigma_m; });
  const auto consistent = [](const Measurement& a, const Measurement& b) {
    const double d = a.s_m - b.s_m;
    return d * d <= 10.83 * (a.gate_sigma_m * a.gate_sigma_m + b.gate_sigma_m * b.gate_sigma_m);
  };
  if (measurements.size() == 2 && !consistent(measurements[0], measurements[1])) {
    est->conflict = true;
  }
  if (!filter.initialised()) {
    refused.reset();
    if (measurements.empty()) return;
    // (Re)initialisation: from the best-supported measurement, and the other if it agrees.
    filter.Initialise(t, measurements[0].s_m, measurements[0].sigma_m);
    *measurements[0].accepted = true;
    confirmed = false;
    if (measurements.size() == 2 && !est->conflict) {
      filter.Update(measurements[1].s_m, measurements[1].sigma_m);
      *measurements[1].accepted = true;
      confirmed = true;  // two independent measurements agree
    }
    if (est->conflict) {
      est->note = fmt::format("{} {:+.2f} m from {}: not used", measurements[1].name,
                              measurements[1].s_m - measurements[0].s_m, measurements[0].name);
    }
    return;
  }
  bool refused = false, accepted = false;
  const double track_sigma_m = filter.sigma_s_m();
  for (const Measurement& m : measurements) {
    if (filter.Accepts(m.s_m, m.gate_sigma_m)) {
      filter.Update(m.s_m, m.sigma_m);
      *m.accepted = true;
      confirmed = true;
      accepted = true;
    } else {
      refused = true;
      AddNote(&est->note, fmt::format("{} {:+.2f} m from the track (sigma {:.2f} m): refused",
                                      m.name, m.s_m - filter.s_m(), m.sigma_m));
    }
  }
  // The track against the evidence: when it refuses the 6-DoF poses of two frames in a row, each
  // better supported than the track (a smaller sigma), and these agree with each other under the
  // motion model, the track was the wrong one (a pose it took from a weak frame, e.g. in a
  // turn); they replace it. One frame alone never does: it may be the wrong one. Epipolar
  // measurements never do: a car driving ahead gives the same wrong line frame after frame, a
  // pose is checked against the map's structure.
  const Refused* previous = this->refused ? &*this->refused : nullptr;
  std::optional<Refused> now;
  for (const Measurement& m : measurements) {
    if (!accepted && m.accepted == &est->pnp_accepted && m.sigma_m < track_sigma_m) {
      now = Refused{t, m.s_m, m.sigma_m, m.gate_sigma_m};
    }
  }
  if (now && previous && confirmed) {
    // The candidate keeps the track's speed (and its uncertainty): a wrong position with the
    // right speed is what a weak frame leaves behind, and two frames a few centimetres apart
    // say little about the speed themselves.
    AlongTrackFilter candidate = filter;
    candidate.Initialise(previous->t, previous->s_m, previous->sigma_m, filter.v_mps(),
                         filter.sigma_v_mps());
    candidate.Predict(t);
    if (candidate.Accepts(now->s_m, now->gate_sigma_m)) {
      AddNote(&est->note,
              fmt::format("track replaced: it refused two frames that agree with each other "
                          "({:+.2f} m from it)",
                          now->s_m - filter.s_m()));
      candidate.Update(now->s_m, now->sigma_m);
      filter = candidate;
      est->pnp_accepted = true;
      est->reinitialised = true;
      ++num_reinitialisations;
      this->refused.reset();
      return;
    }
  }
  this->refused = now;
  if (!confirmed && refused) {
    // The first measurement of this track disagrees with the next one: it was the wrong one
    // as likely as this one. Start again from the next frame.
    filter.Reset();
    AddNote(&est->note, "initialisation not confirmed");
  }
}

StageSeconds& StageSeconds::operator+=(const StageSeconds& o) {
  read += o.read;
  undistort += o.undistort;
  sift += o.sift;
  retrieval += o.retrieval;
  window += o.window;
  match += o.match;
  geometry += o.geometry;
  refine += o.refine;
  other += o.other;
  return *this;
}

Localizer::Localizer(const std::string& db_path,
                     const Camera& query_camera,
                     const LocalizeOptions& options)
    : impl_(std::make_unique<Impl>(db_path, query_camera, options)) {}

Localizer::~Localizer() = default;

PreparedFrame Localizer::Prepare(const QueryFrame& frame) const {
  const auto start = Clock::now();
  const Impl& impl = *impl_;
  PreparedFrame out;
  out.frame = frame.frame;
  out.timestamp_s = frame.timestamp_s;
  out.gnss = frame.gnss;
  out.arrival_s = frame.arrival_s;
  out.where = frame.where;
  EPILOC_CHECK(!frame.image.empty(), "frame {}: empty image", frame.frame);
  SiftOptions sift = impl.options.sift;
  sift.max_num_features = impl.options.max_query_features;
  out.stages.read = frame.read_seconds;
  const cv::Mat working = impl.undistorter.Undistort(ToGrey8(frame.image));
  out.stages.undistort = Seconds(start);
  const auto sift_start = Clock::now();
  out.features = ExtractSift(working, sift);
  out.stages.sift = Seconds(sift_start);
  const auto retrieval_start = Clock::now();
  if (!impl.options.pairs.window_matching) {
    out.index =
        std::make_shared<DescriptorIndex>(out.features.descriptors, impl.options.pairs.match);
  }
  if (impl.retrieval_model) out.global = impl.retrieval_model->Compute(out.features.descriptors);
  out.stages.retrieval = Seconds(retrieval_start);
  out.extraction_seconds = Seconds(start);
  return out;
}

void Localizer::Maintain() {
  Impl& impl = *impl_;
  impl.evaluator->Maintain();
  // The database frames the next frame's tracking window will hold (the filter's prediction one
  // frame interval ahead) are read now, not on that frame's latency. A cache warm-up only.
  if (impl.filter.initialised() && impl.frame_interval_s > 0.0) {
    const double s = impl.filter.s_m() + impl.filter.v_mps() * impl.frame_interval_s;
    const double half_width = impl.options.track_window_m;
    impl.evaluator->Prefetch(impl.Window(s - half_width, s + half_width));
  }
}

FrameEstimate Localizer::Track(const PreparedFrame& query) {
  const auto start = Clock::now();
  Impl& impl = *impl_;
  const LocalizeOptions& options = impl.options;
  FrameEstimate est;
  est.frame = query.frame;
  est.timestamp_s = query.timestamp_s;
  est.extraction_seconds = query.extraction_seconds;
  est.stages = query.stages;
  impl.match_seconds = impl.geometry_seconds = impl.window_seconds = 0.0;
  bool off_route = false;
  if (options.use_gps && query.gnss) {
    est.gnss = query.gnss;
    est.gnss_on_route = impl.route.Project(impl.enu.ToEnu(*query.gnss));
    // Beside the route, or beyond one of its ends, by more than the GPS prior can be wrong.
    const double s_gnss = est.gnss_on_route->s_m;
    off_route = std::abs(est.gnss_on_route->cross_track_m) > options.off_route_m ||
                s_gnss < -options.off_route_m ||
                s_gnss > impl.route.length_m() + options.off_route_m;
  }
  const double t = query.timestamp_s;
  if (impl.last_timestamp_s && t > *impl.last_timestamp_s) {
    impl.frame_interval_s = t - *impl.last_timestamp_s;
  }
  impl.last_timestamp_s = t;
  const int64_t pairs_before = impl.num_pairs;
  AlongTrackFilter& filter = impl.filter;
  if (filter.initialised()) filter.Predict(t);

  // The window: around the prediction while tracking (as wide as its uncertainty), else from
  // retrieval and the GNSS prior.
  std::vector<PairResult> pairs;
  // A prediction much less certain than the tracking window is an unknown speed (the frames after
  // a (re)initialisation, a gap in the input) more than an unknown place: the window around the
  // prediction is searched first, extended toward the side where its pairs place the vehicle,
  // and the rest of the wide window only when that gives no evidence on both sides. The
  // vehicle's first frames then cost what a tracked frame costs, not three times as much.
  std::optional<std::pair<double, double>> rest_of_window;
  if (!off_route) {
    if (filter.initialised()) {
      const double half_width = std::min(std::max(options.track_window_m, 3.0 * filter.sigma_s_m()),
                                         options.gps_window_m);
      double searched = half_width;
      if (half_width > 2.0 * options.track_window_m) {
        searched = options.track_window_m;
        rest_of_window.emplace(filter.s_m() - half_width, filter.s_m() + half_width);
      }
      pairs = impl.Evaluate(query, impl.Window(filter.s_m() - searched, filter.s_m() + searched));
    } else {
      pairs = impl.Initialise(query, est.gnss_on_route, &est.reinitialised);
    }
  }

  // The window must bracket the vehicle (database cameras behind and ahead of it); if every
  // camera is on one side, extend the window on the other, a few times at most.
  for (int extension = 0; extension < kMaxWindowExtensions && !pairs.empty(); ++extension) {
    const int side = OutsideWindow(pairs);
    if (side == 0) break;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const PairResult& p : pairs) {
      lo = std::min(lo, impl.db_s[p.db_index]);
      hi = std::max(hi, impl.db_s[p.db_index]);
    }
    const std::vector<int> more = side > 0 ? impl.Window(lo - options.track_window_m, lo - 1e-6)
                                           : impl.Window(hi + 1e-6, hi + options.track_window_m);
    if (more.empty()) break;  // at an end of the route
    std::vector<PairResult> extra = impl.Evaluate(query, more);
    pairs.insert(pairs.end(), extra.begin(), extra.end());
    ++est.window_extensions;
  }

  if (rest_of_window && !Brackets(pairs)) {
    std::vector<int> rest;
    for (const int j : impl.Window(rest_of_window->first, rest_of_window->second)) {
      if (std::none_of(pairs.begin(), pairs.end(),
                       [j](const PairResult& p) { return p.db_index == j; })) {
        rest.push_back(j);
      }
    }
    std::vector<PairResult> extra = impl.Evaluate(query, rest);
    pairs.insert(pairs.end(), extra.begin(), extra.end());
  }

  est.nearest_db_index = NearestPair(pairs);
  for (const PairResult& p : pairs) {
    if (p.db_index == est.nearest_db_index) est.nearest_inliers = p.num_inliers;
  }
  // Evidence: the epipolar measurement over the pairs that count, and the 6-DoF pose.
  est.epipolar = MeasureAlongTrack(pairs, impl.db_s, impl.undistorter.undistorted_camera().fx,
                                   options.evidence, impl.max_pair_heading_deg);
  if (filter.initialised() && !pairs.empty() && !est.epipolar.valid &&
      !est.epipolar.failure.empty()) {
    AddNote(&est.note, "no epipolar measurement: " + est.epipolar.failure);
  }
  // The 6-DoF pose needs no epipolar estimate: 2D-3D correspondences hold at any relative
  // orientation (a turn into the street, where the V model of d fails), so while no track
  // exists it is also tried around the best-supported pair.
  const int best_supported = BestSupportedPair(pairs);
  if (impl.refine && (est.epipolar.valid || filter.initialised() || best_supported >= 0)) {
    const double reference = filter.initialised() ? filter.s_m()
                             : est.epipolar.valid ? est.epipolar.l_m
                                                  : impl.db_s[best_supported];
    const auto refine_start = Clock::now();
    est.refined = impl.Refine(query, reference, pairs);
    est.stages.refine = Seconds(refine_start);
  }
  impl.Fuse(t, &est);
  const bool updated = est.epipolar_accepted || est.pnp_accepted;
  impl.misses = updated ? 0 : impl.misses + 1;
  if (filter.initialised() && impl.misses >= options.lost_after_frames) {
    filter.Reset();  // lost: the next frame re-initialises
    AddNote(&est.note, "track lost");
  }
  // Beyond the first or last database camera no pair brackets the vehicle: the evidence only
  // extrapolates, and the track would run on along the route's extension.
  const bool beyond_end =
      filter.initialised() && (filter.s_m() < impl.db_s.front() - options.route_end_margin_m ||
                               filter.s_m() > impl.db_s.back() + options.route_end_margin_m);
  if (beyond_end) {
    off_route = true;
    AddNote(&est.note,
            fmt::format("{:.1f} m beyond the route's {}",
                        filter.s_m() < impl.db_s.front() ? impl.db_s.front() - filter.s_m()
                                                         : filter.s_m() - impl.db_s.back(),
                        filter.s_m() < impl.db_s.front() ? "start" : "end"));
  }
  if (filter.initialised() && !impl.confirmed) {
    AddNote(&est.note, "initialising: waiting for a second measurement");
  }
  if (!beyond_end && impl.confirmed && filter.initialised() &&
      filter.sigma_s_m() <= options.max_sigma_m) {
    est.status = TrackStatus::kOk;
    est.s_m = filter.s_m();
    est.sigma_along_m = filter.sigma_s_m();
    est.position = impl.enu.ToGeodetic(impl.route.PointAt(est.s_m));
    const auto nearest = std::lower_bound(impl.db_s.begin(), impl.db_s.end(), est.s_m);
    int j = static_cast<int>(nearest - impl.db_s.begin());
    if (j == impl.num_db_frames() ||
        (j > 0 && est.s_m - impl.db_s[j - 1] < impl.db_s[j] - est.s_m)) {
      --j;
    }
    est.db_index = j;
    est.db_frame = impl.db_frames[j].frame;
    for (const PairResult& p : pairs) {
      if (p.db_index == j) est.num_inliers = p.num_inliers;
    }
  } else {
    est.status = off_route ? TrackStatus::kOffRoute : TrackStatus::kLost;
    if (filter.initialised()) {
      AddNote(&est.note, fmt::format("sigma {:.2f} m", filter.sigma_s_m()));
    } else if (est.note.empty() && !est.epipolar.failure.empty()) {
      est.note = est.epipolar.failure;
    }
  }
  est.num_pairs = static_cast<int>(impl.num_pairs - pairs_before);
  // The point matches served the refinement; dropping them keeps memory flat.
  for (PairResult& p : pairs) {
    p.point_matches.clear();
    p.point_matches.shrink_to_fit();
  }
  if (options.record_offline) {
    RecordedFrame rec;
    rec.frame = query.frame;
    rec.timestamp_s = query.timestamp_s;
    rec.off_route = off_route;
    rec.nearest = est.nearest_db_index;
    for (const PairResult& p : pairs) {
      if (p.valid) rec.valid_pairs.push_back(p);
    }
    impl.record.push_back(std::move(rec));
  }
  if (options.diagnostics) est.pairs = std::move(pairs);
  est.tracking_seconds = Seconds(start);
  est.stages.window = impl.window_seconds;
  est.stages.match = impl.match_seconds;
  est.stages.geometry = impl.geometry_seconds;
  est.stages.other = std::max(0.0, est.tracking_seconds - est.stages.window - est.stages.match -
                                       est.stages.geometry - est.stages.refine);
  return est;
}

int Localizer::Impl::num_db_frames() const { return static_cast<int>(db_frames.size()); }

bool Localizer::refining() const { return impl_->refine; }
const LocalizeOptions& Localizer::options() const { return impl_->options; }
const Camera& Localizer::query_camera() const { return impl_->undistorter.undistorted_camera(); }
int Localizer::num_db_frames() const { return impl_->num_db_frames(); }
frame_t Localizer::db_frame_number(int db_index) const {
  return impl_->db_frames.at(db_index).frame;
}
double Localizer::db_s_m(int db_index) const { return impl_->db_s.at(db_index); }
const Route& Localizer::route() const { return impl_->route; }
int64_t Localizer::num_pairs() const { return impl_->num_pairs; }
int Localizer::num_reinitialisations() const { return impl_->num_reinitialisations; }

}  // namespace epiloc
