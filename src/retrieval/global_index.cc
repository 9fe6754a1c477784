#include <algorithm>
#include <numeric>

#include "epiloc/core/error.h"
#include "epiloc/retrieval/global_descriptor.h"

namespace epiloc {

void GlobalIndex::Add(int64_t id, const Eigen::VectorXf& descriptor) {
  EPILOC_CHECK(descriptor.size() > 0, "global index: empty descriptor for id {}", id);
  if (ids_.empty()) dims_ = static_cast<int>(descriptor.size());
  EPILOC_CHECK(descriptor.size() == dims_,
               "global index: descriptor of id {} has {} values, the index holds {}", id,
               descriptor.size(), dims_);
  EPILOC_CHECK(descriptor.allFinite(), "global index: non-finite descriptor for id {}", id);
  ids_.push_back(id);
  data_.insert(data_.end(), descriptor.data(), descriptor.data() + descriptor.size());
}

void GlobalIndex::Reserve(int64_t num_entries) {
  ids_.reserve(static_cast<size_t>(num_entries));
  if (dims_ > 0) data_.reserve(static_cast<size_t>(num_entries) * dims_);
}

std::vector<std::pair<int64_t, float>> GlobalIndex::Search(const Eigen::VectorXf& query,
                                                           int k) const {
  EPILOC_CHECK(k >= 1, "global index: k must be >= 1, got {}", k);
  if (ids_.empty()) return {};
  EPILOC_CHECK(query.size() == dims_, "global index: query has {} values, the index holds {}",
               query.size(), dims_);
  EPILOC_CHECK(query.allFinite(), "global index: non-finite query");
  const Eigen::Map<const Eigen::MatrixXf> entries(data_.data(), dims_, size());
  const Eigen::VectorXf scores = entries.transpose() * query;
  std::vector<int64_t> order(ids_.size());
  std::iota(order.begin(), order.end(), 0);
  const size_t count = std::min(order.size(), static_cast<size_t>(k));
  std::partial_sort(order.begin(), order.begin() + count, order.end(), [&](int64_t a, int64_t b) {
    return scores[a] > scores[b] || (scores[a] == scores[b] && a < b);
  });
  std::vector<std::pair<int64_t, float>> results;
  results.reserve(count);
  for (size_t i = 0; i < count; ++i) results.emplace_back(ids_[order[i]], scores[order[i]]);
  return results;
}

}  // namespace epiloc
