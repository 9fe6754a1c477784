#include "epiloc/localize/vfit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "epiloc/core/error.h"
#include "epiloc/core/statistics.h"

namespace epiloc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxRefinements = 10;

struct Point {
  double s;
  double d;
  int sign;  // 0 when unknown or when the caller disabled signs
};

struct Model {
  double a = 0.0;
  double l = 0.0;
};

// |d - model(s)|: the signed line for a point with a side, the V otherwise.
double Residual(const Model& m, const Point& p) {
  if (p.sign != 0) return std::abs(p.sign * p.d - m.a * (p.s - m.l));
  return std::abs(p.d - m.a * std::abs(p.s - m.l));
}

double SumSquares(const Model& m, const std::vector<Point>& points, const std::vector<int>& idx) {
  double sum = 0.0;
  for (int i : idx) sum += Residual(m, points[i]) * Residual(m, points[i]);
  return sum;
}

// The exact least-squares V (or line) through points[idx], idx sorted by s with at least two
// distinct s. With every point's side fixed, sigma * d = a s - a l is a straight-line regression;
// the sides of unsigned points follow from l, so each split of the sorted s is tried and kept only
// if its l lies in the split's interval, and l pinned at each sample covers optima on a boundary.
// O(n^2). Returns false when no candidate has a > 0.
bool FitLeastSquares(const std::vector<Point>& points, const std::vector<int>& idx, Model* out) {
  const int n = static_cast<int>(idx.size());
  const double span = points[idx.back()].s - points[idx.front()].s;
  const double eps = 1e-12 * std::max(1.0, span);
  double best_sse = kInf;
  auto consider = [&](const Model& m) {
    if (!(m.a > 0.0) || !std::isfinite(m.l)) return;
    const double sse = SumSquares(m, points, idx);
    if (sse < best_sse) {
      best_sse = sse;
      *out = m;
    }
  };
  for (int t = 0; t <= n; ++t) {  // sorted points [0, t) left of l, [t, n) right
    const double lo = t == 0 ? -kInf : points[idx[t - 1]].s;
    const double hi = t == n ? kInf : points[idx[t]].s;
    double mean_s = 0.0, mean_y = 0.0;
    for (int r = 0; r < n; ++r) {
      const Point& p = points[idx[r]];
      const int side = p.sign != 0 ? p.sign : (r < t ? -1 : 1);
      mean_s += p.s;
      mean_y += side * p.d;
    }
    mean_s /= n;
    mean_y /= n;
    double sxy = 0.0, sxx = 0.0;
    for (int r = 0; r < n; ++r) {
      const Point& p = points[idx[r]];
      const int side = p.sign != 0 ? p.sign : (r < t ? -1 : 1);
      sxy += (p.s - mean_s) * (side * p.d - mean_y);
      sxx += (p.s - mean_s) * (p.s - mean_s);
    }
    Model m;
    m.a = sxy / sxx;
    m.l = mean_s - mean_y / m.a;
    if (m.l >= lo - eps && m.l <= hi + eps) consider(m);
  }
  for (int k = 0; k < n; ++k) {
    Model m;
    m.l = points[idx[k]].s;
    double tu = 0.0, uu = 0.0;
    for (int i : idx) {
      const Point& p = points[i];
      const double u = p.sign != 0 ? p.s - m.l : std::abs(p.s - m.l);
      tu += (p.sign != 0 ? p.sign * p.d : p.d) * u;
      uu += u * u;
    }
    m.a = tu / uu;
    consider(m);
  }
  return best_sse < kInf;
}

// The models through two points: one per choice of their sides (a point with a sign has one).
void PairModels(const Point& p, const Point& q, std::vector<Model>* models) {
  models->clear();
  if (p.s == q.s) return;
  for (int sp : {-1, 1}) {
    if (p.sign != 0 && sp != p.sign) continue;
    for (int sq : {-1, 1}) {
      if (q.sign != 0 && sq != q.sign) continue;
      Model m;
      m.a = (sq * q.d - sp * p.d) / (q.s - p.s);
      if (!(m.a > 0.0)) continue;
      m.l = p.s - sp * p.d / m.a;
      models->push_back(m);
    }
  }
}

// RANSAC over pairs with MSAC scoring (sum of residuals squared, truncated at the threshold).
// Returns the inlier mask of the best model, all points if no pair gives a model.
std::vector<bool> RansacInliers(const std::vector<Point>& points,
                                double threshold,
                                const VFitOptions& options) {
  const int n = static_cast<int>(points.size());
  const double cap = threshold * threshold;
  double best_score = kInf;
  Model best;
  std::vector<Model> models;
  auto try_pair = [&](int i, int j) {
    PairModels(points[i], points[j], &models);
    for (const Model& m : models) {
      double score = 0.0;
      for (const Point& p : points) score += std::min(Residual(m, p) * Residual(m, p), cap);
      if (score < best_score) {
        best_score = score;
        best = m;
      }
    }
  };
  const int64_t num_pairs = int64_t{n} * (n - 1) / 2;
  if (num_pairs <= options.ransac_iterations) {
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n; ++j) try_pair(i, j);
    }
  } else {
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<int> first(0, n - 1), second(0, n - 2);
    for (int it = 0; it < options.ransac_iterations; ++it) {
      const int i = first(rng);
      int j = second(rng);
      if (j >= i) ++j;
      try_pair(i, j);
    }
  }
  std::vector<bool> inliers(n, true);
  if (best_score == kInf) return inliers;
  for (int i = 0; i < n; ++i) inliers[i] = Residual(best, points[i]) <= threshold;
  return inliers;
}

// Indices of the marked points, sorted by s (ties by index, for determinism).
std::vector<int> SortedIndices(const std::vector<Point>& points, const std::vector<bool>& mask) {
  std::vector<int> idx;
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    if (mask[i]) idx.push_back(i);
  }
  std::stable_sort(idx.begin(), idx.end(), [&](int a, int b) { return points[a].s < points[b].s; });
  return idx;
}

bool TwoDistinct(const std::vector<Point>& points, const std::vector<int>& idx) {
  return !idx.empty() && points[idx.back()].s > points[idx.front()].s;
}

}  // namespace

void VFitOptions::Check() const {
  EPILOC_CHECK(std::isfinite(max_residual_fraction) && max_residual_fraction > 0,
               "vfit: max_residual_fraction must be > 0, got {}", max_residual_fraction);
  EPILOC_CHECK(std::isfinite(min_residual) && min_residual >= 0,
               "vfit: min_residual must be >= 0, got {}", min_residual);
  EPILOC_CHECK(min_points >= 2, "vfit: min_points must be >= 2, got {}", min_points);
  EPILOC_CHECK(ransac_iterations >= 1, "vfit: ransac_iterations must be >= 1, got {}",
               ransac_iterations);
}

VFitResult FitV(const std::vector<VFitPoint>& input, const VFitOptions& options) {
  options.Check();
  const int n = static_cast<int>(input.size());
  std::vector<Point> points;
  points.reserve(n);
  for (int i = 0; i < n; ++i) {
    const VFitPoint& p = input[i];
    EPILOC_CHECK(std::isfinite(p.s_m), "vfit: point {}: s_m must be finite, got {}", i, p.s_m);
    EPILOC_CHECK(std::isfinite(p.d) && p.d >= 0,
                 "vfit: point {}: d must be finite and >= 0, got {}", i, p.d);
    EPILOC_CHECK(p.sign >= -1 && p.sign <= 1, "vfit: point {}: sign must be -1, 0 or 1, got {}", i,
                 p.sign);
    points.push_back({p.s_m, p.d, options.use_sign ? p.sign : 0});
  }

  VFitResult result;
  result.inliers.assign(n, false);
  if (n < options.min_points) {
    result.failure = fmt::format("too few points: {} < {}", n, options.min_points);
    return result;
  }
  std::vector<double> ds;
  for (const Point& p : points) ds.push_back(p.d);
  const double threshold = options.max_residual_fraction * Median(ds) + options.min_residual;
  std::vector<int> idx = SortedIndices(points, std::vector<bool>(n, true));
  if (!TwoDistinct(points, idx)) {
    result.failure = "all points at one s";
    return result;
  }

  std::vector<bool> inliers = RansacInliers(points, threshold, options);
  Model model;
  bool fitted = false;
  for (int round = 0; round < kMaxRefinements; ++round) {
    idx = SortedIndices(points, inliers);
    if (!TwoDistinct(points, idx) || !FitLeastSquares(points, idx, &model)) break;
    fitted = true;
    std::vector<bool> next(n);
    for (int i = 0; i < n; ++i) next[i] = Residual(model, points[i]) <= threshold;
    if (next == inliers) break;
    inliers = next;
  }
  if (!fitted) {
    result.failure = "non-positive slope";
    return result;
  }

  // The inliers of the reported model (the loop may stop on its round limit before settling).
  for (int i = 0; i < n; ++i) inliers[i] = Residual(model, points[i]) <= threshold;
  idx = SortedIndices(points, inliers);
  result.inliers = inliers;
  result.num_inliers = static_cast<int>(idx.size());
  result.l_m = model.l;
  result.slope = model.a;
  if (!idx.empty()) {
    result.rms_residual = std::sqrt(SumSquares(model, points, idx) / idx.size());
    result.rms_residual_m = result.rms_residual / model.a;
  }
  if (result.num_inliers < options.min_points) {
    result.failure =
        fmt::format("too few inliers: {} < {}", result.num_inliers, options.min_points);
    return result;
  }
  if (!TwoDistinct(points, idx)) {
    result.failure = "all inliers at one s";
    return result;
  }

  const double s_min = points[idx.front()].s;
  const double s_max = points[idx.back()].s;
  if (model.l <= s_min || model.l >= s_max) {
    std::vector<double> gaps;
    for (size_t r = 1; r < idx.size(); ++r) {
      const double gap = points[idx[r]].s - points[idx[r - 1]].s;
      if (gap > 0) gaps.push_back(gap);
    }
    const double spacing = Median(gaps);
    if (model.l < s_min - spacing || model.l > s_max + spacing) {
      result.failure =
          fmt::format("extrapolation too far: l = {:.3f} m, inliers within [{:.3f}, {:.3f}] m",
                      model.l, s_min, s_max);
      return result;
    }
  }
  result.valid = true;
  return result;
}

}  // namespace epiloc
