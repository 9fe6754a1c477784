#include "epiloc/feature/matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "epiloc/core/error.h"
#include "epiloc/feature/kd_forest.h"

namespace epiloc {

void MatchOptions::Check() const {
  EPILOC_CHECK(ratio > 0 && ratio <= 1, "match: ratio must be in (0, 1], got {}", ratio);
  EPILOC_CHECK(num_trees >= 1, "match: num_trees must be >= 1, got {}", num_trees);
  EPILOC_CHECK(num_checks >= 1, "match: num_checks must be >= 1, got {}", num_checks);
}

std::vector<float> ToRootSift(const FeatureDescriptors& descriptors, int num_rows) {
  std::vector<float> out(static_cast<size_t>(num_rows) * 128);
  for (int i = 0; i < num_rows; ++i) {
    const uint8_t* row = descriptors.row(i).data();
    float sum = 0.0f;
    for (int k = 0; k < 128; ++k) sum += row[k];
    const float scale = sum > 0 ? 1.0f / sum : 0.0f;
    float* dst = out.data() + static_cast<size_t>(i) * 128;
    for (int k = 0; k < 128; ++k) dst[k] = std::sqrt(row[k] * scale);
  }
  return out;
}

struct DescriptorIndex::Impl {
  std::vector<float> data;
  std::unique_ptr<KdForest> index;
};

DescriptorIndex::DescriptorIndex(const FeatureDescriptors& descriptors,
                                 const MatchOptions& options,
                                 int max_rows)
    : options_(options), impl_(std::make_unique<Impl>()) {
  options.Check();
  num_rows_ = static_cast<int>(descriptors.rows());
  if (max_rows >= 0) num_rows_ = std::min(num_rows_, max_rows);
  if (num_rows_ < 2) return;  // nothing to match against (the ratio test needs two)
  impl_->data = ToRootSift(descriptors, num_rows_);
  impl_->index = std::make_unique<KdForest>(options.num_trees);
  impl_->index->Build(impl_->data.data(), static_cast<size_t>(num_rows_));
}

DescriptorIndex::~DescriptorIndex() = default;

std::vector<FeatureMatch> DescriptorIndex::Match(const FeatureDescriptors& other,
                                                 int max_rows) const {
  int num_query = static_cast<int>(other.rows());
  if (max_rows >= 0) num_query = std::min(num_query, max_rows);
  if (!impl_->index || num_query == 0) return {};
  std::vector<float> query = ToRootSift(other, num_query);
  std::vector<size_t> indices(static_cast<size_t>(num_query) * 2);
  std::vector<float> distances(static_cast<size_t>(num_query) * 2);
  impl_->index->Search(query.data(), static_cast<size_t>(num_query), 2, options_.num_checks,
                       indices.data(), distances.data());

  // The forest returns squared distances; the ratio test compares distances.
  const float ratio2 = static_cast<float>(options_.ratio * options_.ratio);
  std::vector<FeatureMatch> best_for_indexed(num_rows_);
  for (int i = 0; i < num_query; ++i) {
    const float d1 = distances[2 * i], d2 = distances[2 * i + 1];
    if (!(d1 < ratio2 * d2)) continue;
    const int a = static_cast<int>(indices[2 * i]);
    FeatureMatch& slot = best_for_indexed[a];
    const float distance = std::sqrt(d1);
    if (slot.index_a < 0 || distance < slot.distance) slot = {a, i, distance};
  }
  std::vector<FeatureMatch> matches;
  for (const FeatureMatch& m : best_for_indexed) {
    if (m.index_a >= 0) matches.push_back(m);
  }
  return matches;
}

}  // namespace epiloc
