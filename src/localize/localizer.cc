#include "epiloc/localize/localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <future>
#include <limits>
#include <memory>
#include <thread>
#include <unordered_map>

#include <spdlog/spdlog.h>

#include "epiloc/camera/undistorter.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/geo/route.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/survey/retrieval_index.h"

namespace epiloc {
namespace {

using Clock = std::chrono::steady_clock;

// Times the evaluated window may be extended in one frame when it does not bracket the vehicle.
constexpr int kMaxWindowExtensions = 3;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

struct QueryFeatures {
  FeatureSet features;
  std::unique_ptr<DescriptorIndex> index;
  Eigen::VectorXf global;  // retrieval descriptor (empty without a retrieval index)
};

// Everything the per-frame methods report, before it becomes result rows.
struct FrameState {
  std::vector<PairResult> pairs;
  std::optional<RouteProjection> gps;
  std::optional<Geodetic> gps_position;
  bool off_route = false;
  int nearest = -1;
  int online_j = -1;
  double online_s = 0.0;
  bool online_ok = false;
  std::optional<PoseRefinement> refined;  // with the refinement, for online-localized frames
};

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

// Which side of the evaluated window the query lies on, from the signs of q_z: +1 if every valid
// database camera is ahead (the query is behind the window), -1 if every one is behind, 0 if the
// window brackets the query (or there is too little evidence to say).
int OutsideWindow(const std::vector<PairResult>& pairs) {
  int ahead = 0, behind = 0;
  for (const PairResult& p : pairs) {
    if (!p.valid) continue;
    (p.signed_distance > 0 ? ahead : behind) += 1;
  }
  if (ahead + behind < 3) return 0;
  if (behind == 0) return +1;
  if (ahead == 0) return -1;
  return 0;
}

// Sub-frame position around database frame j: the V-fit over valid pairs within the window;
// falls back to s_j when the fit is not possible or lands outside the window.
double SubFramePosition(const std::vector<PairResult>& pairs,
                        const std::vector<double>& db_s,
                        int j,
                        const LocalizeOptions& options,
                        VFitResult* fit_out) {
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

}  // namespace

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
  vfit.Check();
  refine.Check();
}

LocalizeRun Localize(const std::string& db_path,
                     const std::string& drive_dir,
                     const LocalizeOptions& options,
                     const ProgressCallback& progress) {
  options.Check();
  const auto start_time = Clock::now();
  Database db(db_path, Database::Mode::kReadOnly);
  const std::optional<Geodetic> origin = db.EnuOrigin();
  EPILOC_CHECK(origin.has_value(), "{}: the database has no frames (no ENU origin)", db_path);
  const EnuFrame enu(*origin);
  const Route route(db.ReadRoute());
  std::vector<DbFrame> db_frames = db.ReadFrames();
  EPILOC_CHECK(db_frames.size() >= 2, "{}: the database holds {} frames, at least 2 needed",
               db_path, db_frames.size());
  std::stable_sort(db_frames.begin(), db_frames.end(),
                   [](const DbFrame& a, const DbFrame& b) { return a.s_m < b.s_m; });
  const int num_db = static_cast<int>(db_frames.size());
  std::vector<double> db_s(num_db);
  LocalizeRun run;
  for (int j = 0; j < num_db; ++j) {
    db_s[j] = db_frames[j].s_m;
    run.db_frame_numbers.push_back(db_frames[j].frame);
  }
  run.db_s_m = db_s;
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
  LocalizeOptions effective = options;
  effective.track_window_m = std::max(options.track_window_m, 2.5 * median_spacing);
  effective.fit_window_m = std::max(options.fit_window_m, 2.5 * median_spacing);
  // A dense survey (a high frame rate, a slow survey vehicle) would put many frames into each
  // window; evaluating frames closer than this adds time, not accuracy.
  const double min_window_spacing_m = 2.0 * effective.track_window_m / options.max_window_frames;
  const Drive drive = LoadDrive(drive_dir);
  const Undistorter undistorter(drive.camera);
  const Camera& query_camera = undistorter.undistorted_camera();
  PairOptions pair_options = options.pairs;
  if (pair_options.min_db_feature_angle_rad == 0) {
    // Database features finer than 3/4 of the finest the query extraction detects cannot match
    // it (the margin allows for the scale change between the two viewpoints).
    pair_options.min_db_feature_angle_rad =
        0.75 * SmallestKeypointSizePx(options.sift, query_camera.width, query_camera.height) /
        query_camera.fx;
  }
  const bool refine = options.refine.enabled && db.NumPoints() > 0;
  if (options.refine.enabled && !refine) {
    spdlog::warn("{}: no triangulated 3-D points (run epiloc triangulate); no 6-DoF refinement",
                 db_path);
  }
  pair_options.with_points = refine;
  run.refined = refine;
  PairEvaluator evaluator(db, db_frames, pair_options);

  // Whole-route image retrieval places the drive without GPS and recovers a lost track.
  std::optional<GlobalDescriptorModel> retrieval_model;
  GlobalIndex retrieval_index;
  std::unordered_map<int64_t, int> db_index_of_image;
  if (HasCurrentRetrievalIndex(db)) {
    retrieval_model.emplace();
    retrieval_index = LoadRetrievalIndex(db, &*retrieval_model);
    for (int j = 0; j < num_db; ++j) db_index_of_image[db_frames[j].image_id] = j;
  } else if (!options.use_gps) {
    Throw("{}: localizing without GPS needs the database's retrieval index (re-run build-db)",
          db_path);
  } else {
    spdlog::warn("{}: no retrieval index; a lost track re-initialises from GPS only", db_path);
  }

  const FrameReader reader(drive);
  const int num_frames = static_cast<int>(drive.frames.size());
  EPILOC_CHECK(num_frames >= 1, "{}: the drive has no frames", drive.dir);
  const int num_threads = options.num_threads > 0
                              ? options.num_threads
                              : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));

  std::vector<FrameState> states(num_frames);
  if (options.use_gps) {
    EPILOC_CHECK(!drive.gnss.samples.empty(),
                 "{}: the drive has no GNSS positions (use --no-gps to localize without)",
                 drive.dir);
    const FramePositions gps = PositionFrames(drive, drive.gnss);
    for (int i = 0; i < num_frames; ++i) {
      if (!gps.per_frame[i]) continue;
      states[i].gps_position = gps.per_frame[i]->position;
      states[i].gps = route.Project(enu.ToEnu(states[i].gps_position.value()));
      states[i].off_route = std::abs(states[i].gps->cross_track_m) > options.off_route_m;
    }
  }

  // Feature extraction runs ahead of the tracker on a second thread.
  auto extract = [&](int i) {
    QueryFeatures q;
    SiftOptions sift = options.sift;
    sift.max_num_features = options.max_query_features;
    q.features = ExtractSift(undistorter.Undistort(reader.ReadGrey(i)), sift);
    if (!options.pairs.window_matching) {
      q.index = std::make_unique<DescriptorIndex>(q.features.descriptors, options.pairs.match);
    }
    if (retrieval_model) q.global = retrieval_model->Compute(q.features.descriptors);
    return q;
  };
  std::deque<std::future<QueryFeatures>> ahead;
  const int prefetch = std::max(1, num_threads);
  for (int i = 0; i < std::min(prefetch, num_frames); ++i) {
    ahead.push_back(std::async(std::launch::async, extract, i));
  }

  SparseCostMatrix costs(num_frames, num_db);
  std::unique_ptr<OnlineDtw> online;
  bool tracking = false;
  int misses = 0;
  double s_est = 0.0, velocity = 0.0, t_est = 0.0;
  bool have_estimate = false;
  for (int i = 0; i < num_frames; ++i) {
    QueryFeatures query = ahead.front().get();
    ahead.pop_front();
    if (i + prefetch < num_frames) {
      ahead.push_back(std::async(std::launch::async, extract, i + prefetch));
    }
    const auto frame_start = Clock::now();
    FrameState& state = states[i];
    const double t = drive.frames[i].timestamp_s;
    FrameDiagnostics diag;
    int diag_extensions = 0;
    diag.frame = drive.frames[i].frame;
    diag.timestamp_s = t;
    if (state.gps) diag.gps_s_m = state.gps->s_m;

    auto evaluate = [&](const std::vector<int>& indices) {
      std::vector<PairResult> r =
          options.pairs.window_matching
              ? evaluator.EvaluateWindow(query_camera, query.features, indices, num_threads)
              : evaluator.Evaluate(query_camera, query.features.keypoints, *query.index, indices,
                                   num_threads);
      run.num_pairs += static_cast<int64_t>(r.size());
      return r;
    };

    if (!state.off_route) {
      if (!tracking) {
        // (Re)initialise: a coarse sweep of the prior window, then the dense window around the
        // best-supported frame.
        // Candidates: the best retrieval matches (inside the GPS window when there is one), or
        // an even sweep of the GPS window without a retrieval index.
        std::vector<int> sweep;
        if (retrieval_model) {
          const int wanted = options.init_candidates;
          const int searched = state.gps ? std::min(num_db, 20 * wanted) : wanted;
          for (const auto& [image_id, score] : retrieval_index.Search(query.global, searched)) {
            const int j = db_index_of_image.at(image_id);
            if (state.gps && std::abs(db_s[j] - state.gps->s_m) > options.gps_window_m) continue;
            sweep.push_back(j);
            if (static_cast<int>(sweep.size()) >= wanted) break;
          }
        }
        if (sweep.empty() && state.gps) {
          const std::vector<int> window = FramesBetween(db_s, state.gps->s_m - options.gps_window_m,
                                                        state.gps->s_m + options.gps_window_m);
          const size_t step = std::max<size_t>(1, window.size() / (2 * options.init_candidates));
          for (size_t k = 0; k < window.size(); k += step) sweep.push_back(window[k]);
        }
        std::sort(sweep.begin(), sweep.end());
        const std::vector<PairResult> coarse = evaluate(sweep);
        int best = -1;
        for (const PairResult& p : coarse) {
          if (p.valid && (best < 0 || p.num_inliers > coarse[best].num_inliers)) {
            best = static_cast<int>(&p - coarse.data());
          }
        }
        if (best >= 0) {
          const double s0 = db_s[coarse[best].db_index];
          state.pairs = evaluate(
              Thinned(FramesBetween(db_s, s0 - effective.track_window_m,
                                    s0 + effective.track_window_m),
                      db_s, min_window_spacing_m));
          diag.reinitialised = true;
          ++run.num_reinitialisations;
        } else {
          state.pairs = coarse;
        }
      } else {
        const double predicted = s_est + velocity * (t - t_est);
        const double margin = effective.track_window_m + 0.5 * std::abs(velocity * (t - t_est));
        state.pairs = evaluate(Thinned(FramesBetween(db_s, predicted - margin, predicted + margin),
                                       db_s, min_window_spacing_m));
      }
    }

    // The window must bracket the vehicle (database cameras behind and ahead of it); if every
    // camera is on one side, extend the window on the other, a few times at most.
    for (int extension = 0; extension < kMaxWindowExtensions && !state.pairs.empty(); ++extension) {
      const int side = OutsideWindow(state.pairs);
      if (side == 0) break;
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (const PairResult& p : state.pairs) {
        lo = std::min(lo, db_s[p.db_index]);
        hi = std::max(hi, db_s[p.db_index]);
      }
      const std::vector<int> more = Thinned(
          side > 0 ? FramesBetween(db_s, lo - effective.track_window_m, lo - 1e-6)
                   : FramesBetween(db_s, hi + 1e-6, hi + effective.track_window_m),
          db_s, min_window_spacing_m);
      if (more.empty()) break;  // at an end of the route
      std::vector<PairResult> extra = evaluate(more);
      state.pairs.insert(state.pairs.end(), extra.begin(), extra.end());
      ++diag_extensions;
    }

    const std::vector<std::pair<int, double>> row = RowCosts(state.pairs);
    for (const auto& [j, cost] : row) costs.Set(i, j, cost);
    state.nearest = NearestPair(state.pairs);

    if (state.nearest >= 0) {
      if (!tracking || !online) {
        if (!online) {
          online = std::make_unique<OnlineDtw>(num_db, state.nearest, options.dtw);
        } else {
          online->Reset(state.nearest);
        }
      }
      state.online_j = online->Push(row);
      VFitResult fit;
      const double s = SubFramePosition(state.pairs, db_s, state.online_j, effective, &fit);
      diag.online_fit = fit;
      state.online_s = s;
      state.online_ok = true;
      if (refine) {
        state.refined = RefinePose(query_camera, query.features.keypoints, state.pairs, s, route,
                                   options.refine);
        if (options.refine.search_by_projection && state.refined->status == RefineStatus::kOk) {
          // The local map: the points seen by the database frames from local_map_behind_m behind
          // to local_map_ahead_m ahead of the estimate (far points constrain the along-track
          // position), the evaluated window's first.
          std::vector<std::shared_ptr<const FrameMapPoints>> local_map;
          for (const PairResult& p : state.pairs) local_map.push_back(evaluator.MapPoints(p.db_index));
          for (const int j : FramesBetween(db_s, s - options.refine.local_map_behind_m,
                                           s + options.refine.local_map_ahead_m)) {
            local_map.push_back(evaluator.MapPoints(j));
          }
          const std::vector<float> root_sift =
              ToRootSift(query.features.descriptors, query.features.size());
          state.refined = RefineByProjection(query_camera, query.features.keypoints, root_sift,
                                             local_map, *state.refined, s, route, options.refine);
        }
      }
      if (have_estimate && t > t_est) {
        const double v = (s - s_est) / (t - t_est);
        velocity = tracking ? 0.5 * velocity + 0.5 * v : 0.0;
      }
      s_est = s;
      t_est = t;
      have_estimate = true;
      tracking = true;
      misses = 0;
      ++run.num_localized_online;
    } else {
      if (online) online->Push(row);
      if (++misses >= options.lost_after_frames) tracking = false;
    }
    // The point matches served the refinement; dropping them keeps memory flat in drive length.
    for (PairResult& p : state.pairs) {
      p.point_matches.clear();
      p.point_matches.shrink_to_fit();
    }
    diag.pairs = state.pairs;
    diag.window_extensions = diag_extensions;
    diag.online_db_index = state.online_j;
    diag.seconds = Seconds(frame_start);
    run.diagnostics.push_back(std::move(diag));
    if (progress) progress(i + 1, num_frames);
  }

  // Result rows.
  run.results.extra_columns = {"fit_residual_m", "inliers", "refine", "cross_track_m",
                               "heading_deg", "reprojection_rmse_px"};
  auto add_row = [&](int i, const std::string& method, ResultStatus status, std::optional<double> s,
                     int db_index, std::optional<Geodetic> position, double residual_m,
                     int inliers) -> ResultRow& {
    ResultRow r;
    r.frame = drive.frames[i].frame;
    r.timestamp_s = drive.frames[i].timestamp_s;
    r.method = method;
    r.status = status;
    if (status == ResultStatus::kOk) {
      r.has_position = true;
      r.position = position ? *position : enu.ToGeodetic(route.PointAt(*s));
      if (s) {
        r.has_s = true;
        r.s_m = *s;
      }
    }
    if (db_index >= 0) r.db_frame = db_frames[db_index].frame;
    r.extra = {std::isfinite(residual_m) ? FormatFixed(residual_m, 4) : "",
               inliers >= 0 ? std::to_string(inliers) : "", "", "", "", ""};
    run.results.rows.push_back(std::move(r));
    return run.results.rows.back();
  };
  auto inliers_at = [&](int i, int j) {
    for (const PairResult& p : states[i].pairs) {
      if (p.db_index == j) return p.num_inliers;
    }
    return -1;
  };
  auto lost_status = [&](int i) {
    return states[i].off_route ? ResultStatus::kOffRoute : ResultStatus::kLost;
  };

  const bool want_online = options.all_methods || options.mode == LocalizeOptions::Mode::kOnline;
  const bool want_free = options.all_methods || options.mode == LocalizeOptions::Mode::kFree;
  const bool want_fixed = options.all_methods || options.mode == LocalizeOptions::Mode::kFixed;

  if (options.all_methods) {
    for (int i = 0; i < num_frames; ++i) {
      const FrameState& st = states[i];
      if (st.gps) {
        add_row(i, "gps", ResultStatus::kOk, st.gps->s_m, -1, st.gps_position, NAN, -1);
      } else {
        add_row(i, "gps", ResultStatus::kLost, std::nullopt, -1, std::nullopt, NAN, -1);
      }
      if (st.nearest >= 0) {
        add_row(i, "nearest", ResultStatus::kOk, db_s[st.nearest], st.nearest,
                db_frames[st.nearest].position, NAN, inliers_at(i, st.nearest));
      } else {
        add_row(i, "nearest", lost_status(i), std::nullopt, -1, std::nullopt, NAN, -1);
      }
    }
  }

  // Offline alignments over the whole sparse cost matrix.
  int first = -1, last = -1;
  for (int i = 0; i < num_frames; ++i) {
    if (states[i].nearest >= 0) {
      if (first < 0) first = i;
      last = i;
    }
  }
  auto offline = [&](const std::string& dtw_name, const std::string& fit_name, bool fixed) {
    DtwResult path;
    if (first >= 0) {
      path = fixed ? AlignFixed(costs, states[first].nearest, states[last].nearest, options.dtw)
                   : AlignFree(costs, states[first].nearest, options.dtw);
    }
    if (!path.valid && first >= 0) {
      spdlog::warn("{} alignment failed: {}", dtw_name, path.failure);
    }
    for (int i = 0; i < num_frames; ++i) {
      const bool ok = path.valid && !states[i].off_route && i >= first && (!fixed || i <= last) &&
                      path.db_index[i] >= 0;
      if (!ok) {
        add_row(i, dtw_name, lost_status(i), std::nullopt, -1, std::nullopt, NAN, -1);
        add_row(i, fit_name, lost_status(i), std::nullopt, -1, std::nullopt, NAN, -1);
        continue;
      }
      const int j = path.db_index[i];
      add_row(i, dtw_name, ResultStatus::kOk, db_s[j], j, db_frames[j].position, NAN,
              inliers_at(i, j));
      VFitResult fit;
      const double s = SubFramePosition(states[i].pairs, db_s, j, effective, &fit);
      add_row(i, fit_name, ResultStatus::kOk, s, j, std::nullopt,
              fit.valid ? fit.rms_residual_m : NAN, fit.num_inliers);
    }
  };
  if (want_fixed) offline("dtw_fixed", "fit_fixed", true);
  if (want_free) offline("dtw_free", "fit_free", false);
  if (want_online) {
    for (int i = 0; i < num_frames; ++i) {
      const FrameState& st = states[i];
      if (st.online_ok) {
        const VFitResult& fit = run.diagnostics[i].online_fit;
        add_row(i, "online", ResultStatus::kOk, st.online_s, st.online_j, std::nullopt,
                fit.valid ? fit.rms_residual_m : NAN, inliers_at(i, st.online_j));
      } else {
        add_row(i, "online", lost_status(i), std::nullopt, -1, std::nullopt, NAN, -1);
      }
    }
  }

  if (refine) {
    // pnp: the refined 6-DoF pose; where the structure is too thin or the pose disagrees with the
    // sequence, the online estimate, flagged in the `refine` column.
    for (int i = 0; i < num_frames; ++i) {
      const FrameState& st = states[i];
      if (!st.online_ok || !st.refined) {
        add_row(i, "pnp", lost_status(i), std::nullopt, -1, std::nullopt, NAN, -1);
        continue;
      }
      const PoseRefinement& ref = *st.refined;
      const VFitResult& fit = run.diagnostics[i].online_fit;
      if (ref.status != RefineStatus::kOk) {
        ResultRow& r = add_row(i, "pnp", ResultStatus::kOk, st.online_s, st.online_j, std::nullopt,
                               fit.valid ? fit.rms_residual_m : NAN, ref.num_inliers);
        r.extra[2] = RefineStatusName(ref.status);
        ++(ref.status == RefineStatus::kThin ? run.num_refine_thin : run.num_refine_rejected);
        continue;
      }
      const Eigen::Vector3d& centre = ref.enu_from_cam.translation;
      const Geodetic position = enu.ToGeodetic(centre);
      ResultRow& r = add_row(i, "pnp", ResultStatus::kOk, ref.projection.s_m, st.online_j, position,
                             NAN, ref.num_inliers);
      const Eigen::Matrix3d rotation = ref.enu_from_cam.rotation.toRotationMatrix();
      r.enu_from_cam =
          Eigen::Quaterniond(enu.EnuFromLocalEnu(position).transpose() * rotation).normalized();
      const Eigen::Vector3d axis = rotation.col(2);
      double heading = std::atan2(axis.x(), axis.y()) * 180.0 / M_PI;
      if (heading < 0) heading += 360.0;
      r.extra[2] = "ok";
      r.extra[3] = FormatFixed(ref.projection.cross_track_m, 3);
      r.extra[4] = FormatFixed(heading, 3);
      r.extra[5] = FormatFixed(ref.rmse_px, 3);
      ++run.num_refined_ok;
    }
  }

  run.num_frames = num_frames;
  run.seconds = Seconds(start_time);
  run.frames_per_second = run.seconds > 0 ? num_frames / run.seconds : 0.0;
  return run;
}

void WriteDiagnosticsCsv(const LocalizeRun& run, const std::string& path) {
  CsvWriter out(path, {"frame", "timestamp_s", "gps_s_m", "db_frame", "db_s_m", "valid", "d",
                       "signed_d", "matches", "inliers", "failure", "online_db_frame", "fit_l_m",
                       "fit_residual_m", "reinitialised", "frame_seconds"});
  for (const FrameDiagnostics& diag : run.diagnostics) {
    const std::string online_frame =
        diag.online_db_index >= 0 ? std::to_string(run.db_frame_numbers[diag.online_db_index]) : "";
    for (const PairResult& p : diag.pairs) {
      out.WriteRow({std::to_string(diag.frame), FormatDouble(diag.timestamp_s),
                    diag.gps_s_m ? FormatFixed(*diag.gps_s_m, 3) : "",
                    std::to_string(run.db_frame_numbers[p.db_index]),
                    FormatFixed(run.db_s_m[p.db_index], 3), p.valid ? "1" : "0",
                    p.valid ? FormatDouble(p.distance) : "",
                    p.valid ? FormatDouble(p.signed_distance) : "", std::to_string(p.num_matches),
                    std::to_string(p.num_inliers), p.failure, online_frame,
                    diag.online_fit.valid ? FormatFixed(diag.online_fit.l_m, 3) : "",
                    diag.online_fit.valid ? FormatFixed(diag.online_fit.rms_residual_m, 4) : "",
                    diag.reinitialised ? "1" : "0", FormatFixed(diag.seconds, 4)});
    }
  }
  out.Close();
}

}  // namespace epiloc
