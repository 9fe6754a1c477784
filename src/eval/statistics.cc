#include "epiloc/eval/statistics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "epiloc/core/error.h"

namespace epiloc {

const std::vector<double>& ErrorThresholds() {
  static const std::vector<double> thresholds = {0.1, 0.25, 0.5, 1.0, 2.0};
  return thresholds;
}

double Percentile(std::vector<double> values, double p) {
  EPILOC_CHECK(!values.empty(), "percentile of no values");
  EPILOC_CHECK(p >= 0.0 && p <= 100.0, "percentile {} outside [0, 100]", p);
  std::sort(values.begin(), values.end());
  const double h = p / 100.0 * static_cast<double>(values.size() - 1);
  const size_t lower = static_cast<size_t>(std::floor(h));
  if (lower + 1 >= values.size()) return values.back();
  return values[lower] + (h - static_cast<double>(lower)) * (values[lower + 1] - values[lower]);
}

ErrorStatistics ComputeErrorStatistics(const std::vector<double>& errors) {
  ErrorStatistics stats;
  stats.count = static_cast<int64_t>(errors.size());
  const size_t num_thresholds = ErrorThresholds().size();
  if (errors.empty()) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    stats.min = stats.max = stats.mean_abs = stats.bias = stats.std = nan;
    stats.median_abs = stats.rmse = stats.p95_abs = nan;
    stats.share_within.assign(num_thresholds, nan);
    return stats;
  }
  const double n = static_cast<double>(errors.size());
  std::vector<double> abs_errors;
  abs_errors.reserve(errors.size());
  double sum = 0.0, sum_abs = 0.0, sum_sq = 0.0;
  stats.min = stats.max = errors.front();
  for (const double e : errors) {
    EPILOC_CHECK(std::isfinite(e), "error statistics: non-finite error {}", e);
    stats.min = std::min(stats.min, e);
    stats.max = std::max(stats.max, e);
    sum += e;
    sum_abs += std::abs(e);
    sum_sq += e * e;
    abs_errors.push_back(std::abs(e));
  }
  stats.bias = sum / n;
  stats.mean_abs = sum_abs / n;
  stats.rmse = std::sqrt(sum_sq / n);
  double sum_dev = 0.0;  // two-pass for accuracy
  for (const double e : errors) sum_dev += (e - stats.bias) * (e - stats.bias);
  stats.std = std::sqrt(sum_dev / n);
  stats.median_abs = Percentile(abs_errors, 50.0);
  stats.p95_abs = Percentile(abs_errors, 95.0);
  for (const double t : ErrorThresholds()) {
    const auto within =
        std::count_if(abs_errors.begin(), abs_errors.end(), [t](double a) { return a <= t; });
    stats.share_within.push_back(static_cast<double>(within) / n);
  }
  return stats;
}

}  // namespace epiloc
