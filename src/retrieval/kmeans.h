// K-means on RootSIFT descriptors, private to the retrieval module.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace epiloc {
namespace internal {

// One descriptor per row.
using DescriptorMatrixF = Eigen::Matrix<float, Eigen::Dynamic, 128, Eigen::RowMajor>;

// Index of the nearest row of `centres` (squared L2; ties to the lower index) for each row of
// `data`, and optionally that squared distance. With `parallel`, rows are split over up to
// hardware_concurrency() threads (same result).
void AssignNearest(const Eigen::Ref<const DescriptorMatrixF>& data,
                   const DescriptorMatrixF& centres,
                   bool parallel,
                   std::vector<int>* labels,
                   std::vector<float>* squared_distances = nullptr);

// Lloyd's k-means with k-means++ seeding (Arthur & Vassilvitskii 2007) from std::mt19937_64(seed)
// with portable sampling, so the result is the same on every platform. Stops when no assignment
// changes or after max_iterations; an empty cluster is re-seeded with the point farthest from its
// centre. Requires data.rows() >= k >= 1.
DescriptorMatrixF KMeans(const DescriptorMatrixF& data, int k, uint64_t seed, int max_iterations);

}  // namespace internal
}  // namespace epiloc
