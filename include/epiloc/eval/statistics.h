// Summary statistics of a set of (signed) errors, as tabulated by `epiloc evaluate`.
#pragma once

#include <cstdint>
#include <vector>

namespace epiloc {

// The thresholds of the "share of frames within" rows, metres: 0.1, 0.25, 0.5, 1, 2.
const std::vector<double>& ErrorThresholds();

// The p-th percentile (p in [0, 100]) of `values` by linear interpolation between order
// statistics (numpy's default, "linear", Hyndman & Fan type 7): with the values sorted
// x_0 <= ... <= x_{n-1} and h = p / 100 * (n - 1), the result is
// x_floor(h) + (h - floor(h)) * (x_floor(h)+1 - x_floor(h)). Throws Error if `values` is empty or
// p is outside [0, 100].
double Percentile(std::vector<double> values, double p);

// Statistics of errors e_i in metres (n = count). NaN for every figure when count == 0.
struct ErrorStatistics {
  int64_t count = 0;
  double min = 0.0;         // smallest signed e_i
  double max = 0.0;         // largest signed e_i
  double mean_abs = 0.0;    // mean of |e_i|
  double bias = 0.0;        // mean of e_i (signed)
  double std = 0.0;         // population standard deviation of e_i: sqrt(mean((e_i - bias)^2))
  double median_abs = 0.0;  // Percentile(|e|, 50)
  double rmse = 0.0;        // sqrt(mean(e_i^2)) (= sqrt(bias^2 + std^2))
  double p95_abs = 0.0;     // Percentile(|e|, 95)
  std::vector<double> share_within;  // per ErrorThresholds() t: share of frames with |e_i| <= t
};

ErrorStatistics ComputeErrorStatistics(const std::vector<double>& errors);

}  // namespace epiloc
