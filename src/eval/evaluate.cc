#include "epiloc/eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/geo/route.h"

namespace epiloc {
namespace {

// Ground truth of a row, with the index of the nearest truth sample in time (the hint of its
// projection onto the route).
struct Match {
  Geodetic position;
  size_t nearest = 0;
  std::optional<Eigen::Quaterniond> enu_from_cam;  // local ENU at `position`
  double timestamp_s = 0.0;                        // of the truth sample (frame association)
};

class TruthMatcher {
 public:
  TruthMatcher(const PositionTrack& truth, Association association, double max_gap_s)
      : truth_(truth), association_(association), max_gap_s_(max_gap_s) {
    for (size_t i = 0; i < truth.samples.size(); ++i) {
      if (truth.samples[i].frame != kInvalidFrame) by_frame_.emplace(truth.samples[i].frame, i);
    }
  }

  std::optional<Match> Find(const ResultRow& row) const {
    if (association_ == Association::kFrame) {
      const auto it = by_frame_.find(row.frame);
      if (row.frame == kInvalidFrame || it == by_frame_.end()) return std::nullopt;
      const PositionSample& s = truth_.samples[it->second];
      return Match{s.position, it->second, s.enu_from_cam, s.timestamp_s};
    }
    const auto sample = truth_.Interpolate(row.timestamp_s, max_gap_s_);
    if (!sample) return std::nullopt;
    return Match{sample->position, NearestInTime(row.timestamp_s), sample->enu_from_cam,
                 row.timestamp_s};
  }

 private:
  size_t NearestInTime(double t) const {
    const auto& s = truth_.samples;
    const auto it = std::lower_bound(
        s.begin(), s.end(), t, [](const PositionSample& a, double b) { return a.timestamp_s < b; });
    const size_t i = static_cast<size_t>(it - s.begin());
    if (i == 0) return 0;
    if (i == s.size()) return s.size() - 1;
    return t - s[i - 1].timestamp_s <= s[i].timestamp_s - t ? i - 1 : i;
  }

  const PositionTrack& truth_;
  Association association_;
  double max_gap_s_;
  std::map<frame_t, size_t> by_frame_;
};

Association ChooseAssociation(const ResultTable& result,
                              const PositionTrack& truth,
                              Association requested) {
  if (requested != Association::kAuto) return requested;
  const bool truth_frames = std::all_of(truth.samples.begin(), truth.samples.end(),
                                        [](const PositionSample& s) { return s.frame >= 0; });
  const bool result_frames = std::all_of(result.rows.begin(), result.rows.end(), [](const auto& r) {
    return r.status != ResultStatus::kOk || r.frame != kInvalidFrame;
  });
  return truth_frames && result_frames ? Association::kFrame : Association::kTime;
}

// Milliseconds of a UNIX time, but never hundreds of digits for an absurd one (1.8e308).
std::string TimeRange(double first, double last) {
  return fmt::format("{:.13g}..{:.13g} s", first, last);
}

// The ok rows' time span (for the "no overlap" message).
std::pair<double, double> OkTimeSpan(const ResultTable& result) {
  double first = INFINITY, last = -INFINITY;
  for (const auto& row : result.rows) {
    if (row.status != ResultStatus::kOk) continue;
    first = std::min(first, row.timestamp_s);
    last = std::max(last, row.timestamp_s);
  }
  return {first, last};
}

void Summarize(MethodEvaluation& m) {
  std::sort(m.frames.begin(), m.frames.end(),
            [](const FrameError& a, const FrameError& b) { return a.timestamp_s < b.timestamp_s; });
  std::vector<double> along, cross, horizontal, vertical, full, rotation;
  for (const auto& f : m.frames) {
    along.push_back(f.along_track_m);
    cross.push_back(f.cross_track_m);
    horizontal.push_back(f.horizontal_m);
    vertical.push_back(f.vertical_m);
    full.push_back(f.error_3d_m);
    if (std::isfinite(f.rotation_deg)) rotation.push_back(f.rotation_deg);
  }
  m.rotation = ComputeErrorStatistics(rotation);
  m.along_track = ComputeErrorStatistics(along);
  m.cross_track = ComputeErrorStatistics(cross);
  m.horizontal = ComputeErrorStatistics(horizontal);
  m.vertical = ComputeErrorStatistics(vertical);
  m.error_3d = ComputeErrorStatistics(full);
  const auto calibration = [&](auto error, auto sigma) {
    Calibration c;
    int64_t within = 0;
    for (const auto& f : m.frames) {
      if (!std::isfinite(sigma(f))) continue;
      ++c.count;
      within += std::abs(error(f)) <= 2.0 * sigma(f) ? 1 : 0;
    }
    if (c.count > 0) c.share_within_2_sigma = static_cast<double>(within) / c.count;
    return c;
  };
  m.along_calibration = calibration([](const FrameError& f) { return f.along_track_m; },
                                    [](const FrameError& f) { return f.sigma_along_m; });
  m.horizontal_calibration = calibration([](const FrameError& f) { return f.horizontal_m; },
                                         [](const FrameError& f) { return f.sigma_horizontal_m; });
}

// The value of an extra column of a row as a positive number, NaN if absent, empty or invalid.
double ExtraSigma(const ResultTable& result, const ResultRow& row, const std::string& column) {
  const auto it = std::find(result.extra_columns.begin(), result.extra_columns.end(), column);
  if (it == result.extra_columns.end()) return NAN;
  const std::string& text = row.extra[static_cast<size_t>(it - result.extra_columns.begin())];
  if (text.empty()) return NAN;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0' && value > 0 && std::isfinite(value) ? value : NAN;
}

}  // namespace

Association ParseAssociation(const std::string& name) {
  if (name == "auto") return Association::kAuto;
  if (name == "frame") return Association::kFrame;
  if (name == "time") return Association::kTime;
  Throw("unknown association '{}' (known: auto, frame, time)", name);
}

std::string AssociationName(Association association) {
  switch (association) {
    case Association::kAuto:
      return "auto";
    case Association::kFrame:
      return "frame";
    case Association::kTime:
      return "time";
  }
  return "?";
}

void EvaluateOptions::Check() const {
  EPILOC_CHECK(std::isfinite(max_gap_s) && max_gap_s >= 0.0, "--max-gap-s must be >= 0, got {}",
               max_gap_s);
  EPILOC_CHECK(std::isfinite(projection_window_m) && projection_window_m > 0.0,
               "projection window must be > 0 m, got {}", projection_window_m);
  EPILOC_CHECK(std::isfinite(on_route_m) && on_route_m >= 0.0, "--on-route-m must be >= 0, got {}",
               on_route_m);
}

const MethodEvaluation* Evaluation::Find(const std::string& method) const {
  for (const auto& m : methods) {
    if (m.method == method) return &m;
  }
  return nullptr;
}

Evaluation Evaluate(const ResultTable& result,
                    const PositionTrack& truth,
                    const EvaluationRoute& route_in,
                    const EvaluateOptions& options) {
  options.Check();
  EPILOC_CHECK(!truth.samples.empty(), "{}: the ground truth has no positions", truth.source);
  EPILOC_CHECK(!result.rows.empty(), "{}: no rows (an empty result)", result.path);
  Evaluation eval;
  eval.route = route_in;
  eval.max_gap_s = options.max_gap_s;
  eval.association = ChooseAssociation(result, truth, options.association);
  const EnuFrame enu(route_in.origin);
  const Route route = [&] {
    try {
      return Route(route_in.points_in_enu);
    } catch (const Error& e) {
      Throw("{}: {} (give --route or --route-drive)", route_in.source, e.what());
    }
  }();
  eval.route_length_m = route.length_m();
  const double window = options.projection_window_m;

  for (size_t i = 0; i < truth.samples.size(); ++i) {
    const Eigen::Vector3d p = enu.ToEnu(truth.samples[i].position);
    eval.truth_in_enu.push_back(p);
    eval.truth_s_m.push_back(i == 0 ? route.Project(p).s_m
                                    : route.ProjectNear(p, eval.truth_s_m.back(), window).s_m);
  }

  const TruthMatcher matcher(truth, eval.association, options.max_gap_s);
  std::map<std::string, MethodEvaluation> by_method;
  // Frame association trusts the frame numbers; times far apart say they are of another drive.
  struct TimeDisagreement {
    int64_t rows = 0;
    double largest_s = 0.0;
    frame_t frame = kInvalidFrame;
  };
  std::map<std::string, TimeDisagreement> disagreements;
  for (const auto& row : result.rows) {
    MethodEvaluation& m = by_method[row.method];
    m.method = row.method;
    ++m.rows;
    ++m.by_status[static_cast<size_t>(row.status)];
    const auto match = matcher.Find(row);
    if (match) {
      // Where the vehicle really was: on the surveyed route, or before / after / beside it.
      const RouteProjection t = route.ProjectNear(enu.ToEnu(match->position),
                                                  eval.truth_s_m[match->nearest], window);
      const bool on_route = t.within && std::abs(t.cross_track_m) <= options.on_route_m;
      const bool ok = row.status == ResultStatus::kOk;
      ++(on_route ? m.truth_on_route : m.truth_off_route);
      if (ok) ++(on_route ? m.ok_on_route : m.ok_off_route);
    }
    if (row.status != ResultStatus::kOk) continue;
    if (!match) {
      ++m.unmatched;
      m.unmatched_frames.push_back(row.frame);
      m.unmatched_times_s.push_back(row.timestamp_s);
      continue;
    }
    const double time_difference_s = std::abs(row.timestamp_s - match->timestamp_s);
    if (eval.association == Association::kFrame && time_difference_s > options.max_gap_s) {
      TimeDisagreement& d = disagreements[row.method];
      ++d.rows;
      if (time_difference_s > d.largest_s) {
        d.largest_s = time_difference_s;
        d.frame = row.frame;
      }
    }
    FrameError f;
    f.frame = row.frame;
    f.timestamp_s = row.timestamp_s;
    f.truth_in_enu = enu.ToEnu(match->position);
    f.estimate_in_enu = enu.ToEnu(row.position);
    const RouteProjection t =
        route.ProjectNear(f.truth_in_enu, eval.truth_s_m[match->nearest], window);
    const RouteProjection e = route.ProjectNear(f.estimate_in_enu, t.s_m, window);
    f.truth_s_m = t.s_m;
    f.estimate_s_m = e.s_m;
    f.along_track_m = e.s_m - t.s_m;
    f.cross_track_m = e.cross_track_m - t.cross_track_m;
    const Eigen::Vector3d d = f.estimate_in_enu - f.truth_in_enu;
    f.horizontal_m = d.head<2>().norm();
    f.vertical_m = d.z();
    f.error_3d_m = d.norm();
    if (row.enu_from_cam && match->enu_from_cam) {
      // Both orientations are given in the local ENU at their own position.
      const Eigen::Quaterniond estimate(enu.EnuFromLocalEnu(row.position) *
                                        row.enu_from_cam->toRotationMatrix());
      const Eigen::Quaterniond truth_q(enu.EnuFromLocalEnu(match->position) *
                                       match->enu_from_cam->toRotationMatrix());
      f.rotation_deg = RotationDifferenceDeg(estimate, truth_q);
    }
    f.sigma_along_m = ExtraSigma(result, row, "sigma_along_m");
    f.sigma_horizontal_m = ExtraSigma(result, row, "sigma_horizontal_m");
    m.frames.push_back(f);
  }

  int64_t evaluated = 0;
  for (const auto& name : result.Methods()) {
    MethodEvaluation& m = by_method.at(name);
    Summarize(m);
    evaluated += m.evaluated();
    if (m.unmatched > 0) {
      constexpr size_t kShown = 8;
      std::vector<std::string> shown;
      for (size_t i = 0; i < std::min(kShown, m.unmatched_frames.size()); ++i) {
        shown.push_back(m.unmatched_frames[i] == kInvalidFrame
                            ? fmt::format("t={:.13g}", m.unmatched_times_s[i])
                            : std::to_string(m.unmatched_frames[i]));
      }
      std::string warning = fmt::format(
          "method {}: {} of {} ok frames have no ground truth ({}), not evaluated: {}{}", name,
          m.unmatched, m.ok(),
          eval.association == Association::kFrame
              ? "frame number absent from the ground truth"
              : fmt::format("no ground truth within --max-gap-s {} s", options.max_gap_s),
          fmt::join(shown, ", "), m.unmatched_frames.size() > kShown ? ", ..." : "");
      eval.warnings.push_back(std::move(warning));
    }
    if (const auto it = disagreements.find(name); it != disagreements.end()) {
      eval.warnings.push_back(fmt::format(
          "method {}: {} of {} rows matched by frame number are more than --max-gap-s {} s from "
          "their ground truth in time (up to {:.6g} s, frame {}): is it the ground truth of this "
          "drive?",
          name, it->second.rows, m.ok(), options.max_gap_s, it->second.largest_s, it->second.frame));
    }
    eval.methods.push_back(std::move(m));
  }
  if (evaluated == 0) {
    const auto [first, last] = OkTimeSpan(result);
    if (first > last) {
      Throw("{}: no row has status ok, nothing to evaluate", result.path);
    }
    if (eval.association == Association::kFrame) {
      Throw(
          "{}: no frame number of the result occurs in the ground truth {} (association by "
          "frame; try --associate time)",
          result.path, truth.source);
    }
    Throw(
        "{}: no overlap in time with the ground truth {} (ok rows at {}, ground truth at {}, "
        "--max-gap-s {})",
        result.path, truth.source, TimeRange(first, last),
        TimeRange(truth.samples.front().timestamp_s, truth.samples.back().timestamp_s),
        options.max_gap_s);
  }
  for (const auto& warning : eval.warnings) spdlog::warn("{}", warning);
  return eval;
}

std::vector<ResultRow> GnssBaselineRows(const PositionTrack& gnss,
                                        const std::vector<FrameRecord>& frames,
                                        double max_gap_s) {
  std::vector<ResultRow> rows;
  for (const auto& frame : frames) {
    ResultRow row;
    row.method = "gps";
    row.frame = frame.frame;
    row.timestamp_s = frame.timestamp_s;
    if (const auto sample = gnss.Interpolate(frame.timestamp_s, max_gap_s)) {
      row.position = sample->position;
      row.has_position = true;
      row.status = ResultStatus::kOk;
    } else {
      row.status = ResultStatus::kLost;
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace epiloc
