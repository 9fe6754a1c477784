#include "epiloc/localize/evidence.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

struct Point {
  int pair = -1;  // index into the input pairs
  double s = 0.0;
  double u = 0.0;      // signed cot of the baseline's angle: f d sign(q_z)
  double sigma = 0.0;  // of u
};

struct Line {
  double a = 0.0;  // slope A = 1 / |Δy|
  double l = 0.0;  // x-intercept
  double Residual(const Point& p) const { return (p.u - a * (p.s - l)) / p.sigma; }
};

// Weighted least squares of u = A (s - l) over `points`; false when degenerate or A <= 0.
bool FitWeighted(
    const std::vector<Point>& points, Line* line, double* sum_w, double* mean_s, double* sxx) {
  double w_sum = 0.0, ws = 0.0, wu = 0.0;
  for (const Point& p : points) {
    const double w = 1.0 / (p.sigma * p.sigma);
    w_sum += w;
    ws += w * p.s;
    wu += w * p.u;
  }
  if (!(w_sum > 0)) return false;
  const double s_bar = ws / w_sum, u_bar = wu / w_sum;
  double xx = 0.0, xu = 0.0;
  for (const Point& p : points) {
    const double w = 1.0 / (p.sigma * p.sigma);
    xx += w * (p.s - s_bar) * (p.s - s_bar);
    xu += w * (p.s - s_bar) * (p.u - u_bar);
  }
  if (!(xx > 0)) return false;
  line->a = xu / xx;
  if (!(line->a > 0) || !std::isfinite(line->a)) return false;
  line->l = s_bar - u_bar / line->a;
  *sum_w = w_sum;
  *mean_s = s_bar;
  *sxx = xx;
  return std::isfinite(line->l);
}

}  // namespace

void EvidenceOptions::Check() const {
  EPILOC_CHECK(min_relative_support >= 0 && min_relative_support < 1,
               "evidence: min_relative_support must be in [0, 1)");
  EPILOC_CHECK(feature_sigma_px > 0, "evidence: feature_sigma_px must be > 0");
  EPILOC_CHECK(outlier_sigmas > 0, "evidence: outlier_sigmas must be > 0");
  EPILOC_CHECK(min_pairs >= 2, "evidence: min_pairs must be >= 2");
  EPILOC_CHECK(max_lateral_offset_m > 0, "evidence: max_lateral_offset_m must be > 0");
  EPILOC_CHECK(floor_sigma_m >= 0, "evidence: floor_sigma_m must be >= 0");
  EPILOC_CHECK(pnp_floor_sigma_m >= 0, "evidence: pnp_floor_sigma_m must be >= 0");
}

const char* PairVerdictName(PairVerdict verdict) {
  switch (verdict) {
    case PairVerdict::kUsed:
      return "used";
    case PairVerdict::kFailed:
      return "failed";
    case PairVerdict::kWeakSupport:
      return "weak support";
    case PairVerdict::kInconsistent:
      return "inconsistent with its neighbours";
    case PairVerdict::kTurnedAway:
      return "turned away from the database camera";
  }
  return "?";
}

AlongTrackMeasurement MeasureAlongTrack(const std::vector<PairResult>& pairs,
                                        const std::vector<double>& db_s_m,
                                        double focal_px,
                                        const EvidenceOptions& options,
                                        double max_heading_deg) {
  AlongTrackMeasurement out;
  out.verdicts.assign(pairs.size(), PairVerdict::kFailed);
  int best_inliers = 0;
  for (const PairResult& p : pairs) {
    if (p.valid) best_inliers = std::max(best_inliers, p.num_inliers);
  }
  std::vector<Point> points;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const PairResult& p = pairs[k];
    if (!p.valid) continue;
    if (std::abs(p.heading_deg) > max_heading_deg) {
      out.verdicts[k] = PairVerdict::kTurnedAway;
      continue;
    }
    if (p.num_inliers < options.min_relative_support * best_inliers) {
      out.verdicts[k] = PairVerdict::kWeakSupport;
      continue;
    }
    Point point;
    point.pair = static_cast<int>(k);
    point.s = db_s_m.at(p.db_index);
    point.u = p.signed_cot;
    // σ_φ ≈ σ_px / (f p √N); the parallax check of the epipole keeps p away from zero.
    const double parallax_rad = std::max(p.parallax_deg, 0.01) * kDegToRad;
    const double sigma_angle = options.feature_sigma_px /
                               (focal_px * parallax_rad * std::sqrt(std::max(1, p.num_inliers)));
    point.sigma = sigma_angle * (1.0 + point.u * point.u);
    if (!std::isfinite(point.u) || !(point.sigma > 0) || !std::isfinite(point.sigma)) {
      out.verdicts[k] = PairVerdict::kInconsistent;
      continue;
    }
    points.push_back(point);
    out.verdicts[k] = PairVerdict::kInconsistent;  // until a line takes it
  }
  if (static_cast<int>(points.size()) < options.min_pairs) {
    for (const Point& p : points) out.verdicts[p.pair] = PairVerdict::kUsed;
    out.num_used = static_cast<int>(points.size());
    out.failure = "too few pairs with support";
    return out;
  }

  // RANSAC over every pair of points (a window holds a few dozen at most), MSAC scoring.
  const double cap = options.outlier_sigmas * options.outlier_sigmas;
  double best_score = std::numeric_limits<double>::infinity();
  Line best;
  for (size_t i = 0; i < points.size(); ++i) {
    for (size_t j = i + 1; j < points.size(); ++j) {
      if (points[i].s == points[j].s) continue;
      Line line;
      line.a = (points[j].u - points[i].u) / (points[j].s - points[i].s);
      if (!(line.a > 0) || !std::isfinite(line.a)) continue;
      line.l = points[i].s - points[i].u / line.a;
      double score = 0.0;
      for (const Point& p : points) {
        const double r = line.Residual(p);
        score += std::min(r * r, cap);
      }
      if (score < best_score) {
        best_score = score;
        best = line;
      }
    }
  }
  if (!std::isfinite(best_score)) {
    out.failure = "no line through the pairs";
    return out;
  }
  // Least squares on the consistent pairs, re-selected until they settle.
  std::vector<Point> used;
  Line line = best;
  double sum_w = 0.0, mean_s = 0.0, sxx = 0.0, scale2 = 1.0;
  bool fitted = false;
  for (int round = 0; round < 5; ++round) {
    std::vector<Point> next;
    const double threshold = options.outlier_sigmas * std::sqrt(std::max(1.0, scale2));
    for (const Point& p : points) {
      if (std::abs(line.Residual(p)) <= threshold) next.push_back(p);
    }
    if (static_cast<int>(next.size()) < 2) break;
    Line fit;
    if (!FitWeighted(next, &fit, &sum_w, &mean_s, &sxx)) break;
    double rss = 0.0;
    for (const Point& p : next) rss += fit.Residual(p) * fit.Residual(p);
    scale2 = next.size() > 2 ? rss / static_cast<double>(next.size() - 2) : 1.0;
    const bool same = next.size() == used.size() &&
                      std::equal(next.begin(), next.end(), used.begin(),
                                 [](const Point& a, const Point& b) { return a.pair == b.pair; });
    used = std::move(next);
    line = fit;
    fitted = true;
    if (same) break;
  }
  if (!fitted) {
    out.failure = "degenerate line";
    return out;
  }
  for (const Point& p : used) {
    out.verdicts[p.pair] = PairVerdict::kUsed;
    ((p.s > line.l) ? out.num_ahead : out.num_behind) += 1;
  }
  out.num_used = static_cast<int>(used.size());
  out.residual_scale = std::sqrt(scale2);
  out.lateral_offset_m = 1.0 / line.a;
  out.l_m = line.l;
  // Var(l) = σ² / A² (1 / Σw + (l - s̄)² / Sxx), σ² the residual scale (never below 1).
  const double var = std::max(1.0, scale2) / (line.a * line.a) *
                     (1.0 / sum_w + (line.l - mean_s) * (line.l - mean_s) / sxx);
  // No single pair may decide the position: the jackknife's variance of l over the fits that
  // leave one used pair out (Efron & Stein) is a floor of the model's. A wrong essential matrix
  // with a confident direction (repeated texture, a camera turned away from the database's view)
  // is consistent with a line through pairs far ahead, whose directions say little; without it
  // the line lands elsewhere. A line that the absence of one pair leaves undefined (no slope
  // left, or a negative one) is no measurement.
  double jackknife_var = 0.0;
  bool one_pair_decides = false;
  if (used.size() >= 3) {
    std::vector<double> ls;
    std::vector<Point> rest;
    for (size_t i = 0; i < used.size(); ++i) {
      rest.assign(used.begin(), used.end());
      rest.erase(rest.begin() + static_cast<std::ptrdiff_t>(i));
      Line without;
      double w = 0.0, m = 0.0, x = 0.0;
      if (!FitWeighted(rest, &without, &w, &m, &x)) {
        ls.clear();
        one_pair_decides = true;
        break;
      }
      ls.push_back(without.l);
    }
    if (!ls.empty()) {
      double mean = 0.0;
      for (const double l : ls) mean += l;
      mean /= static_cast<double>(ls.size());
      for (const double l : ls) jackknife_var += (l - mean) * (l - mean);
      jackknife_var *= static_cast<double>(ls.size() - 1) / static_cast<double>(ls.size());
    }
  }
  out.model_sigma_m = std::sqrt(var + options.floor_sigma_m * options.floor_sigma_m);
  out.sigma_m =
      std::sqrt(std::max(var, jackknife_var) + options.floor_sigma_m * options.floor_sigma_m);
  // Each pair's sign says on which side of the vehicle its camera is. A line whose intercept puts
  // a camera on the other side (farther than 2 sigma of l: beside the vehicle the sign is
  // uncertain) contradicts the pairs it was fitted to: nearly equal u on one side (the vehicle
  // far beyond the last camera, past the route's end) leave a flat, unconstrained line.
  int contradicted = 0;
  for (const Point& p : used) {
    const double beyond = p.s - line.l;  // > 0: the camera should be ahead (u > 0)
    if (std::abs(beyond) > 2.0 * out.sigma_m && (beyond > 0) != (p.u > 0)) ++contradicted;
  }
  if (out.num_used < options.min_pairs) {
    out.failure = "too few consistent pairs";
  } else if (out.lateral_offset_m > options.max_lateral_offset_m) {
    out.failure = "the pairs' directions show no road geometry";
  } else if (one_pair_decides) {
    out.failure = "one pair decides the line";
  } else if (!std::isfinite(out.sigma_m)) {
    out.failure = "no uncertainty";
  } else if (contradicted > 0) {
    out.failure = fmt::format("the line puts {} of its pairs' cameras on the wrong side",
                              contradicted);
  } else {
    out.valid = true;
  }
  return out;
}

}  // namespace epiloc
