#include "epiloc/core/statistics.h"

#include <algorithm>
#include <cstddef>

namespace epiloc {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  if (values.size() % 2 == 1) return *mid;
  // nth_element leaves the lower half before mid: its largest is the other middle value.
  return 0.5 * (*mid + *std::max_element(values.begin(), mid));
}

double UpperMedian(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace epiloc
