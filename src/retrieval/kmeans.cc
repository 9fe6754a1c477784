// GCC 12 reports a false "iteration ... invokes undefined behavior" inside Eigen's matrix-vector
// kernel instantiated by the distance product below (never reached with these sizes).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Waggressive-loop-optimizations"
#endif

#include "kmeans.h"

#include <algorithm>
#include <limits>
#include <random>
#include <thread>

#include "epiloc/core/error.h"

namespace epiloc {
namespace internal {
namespace {

// Rows per block of the distance computation: bounds the temporary block x k matrix.
constexpr Eigen::Index kBlockRows = 2048;
// Below this many rows threads cost more than they save.
constexpr Eigen::Index kMinParallelRows = 8192;

void AssignRange(const Eigen::Ref<const DescriptorMatrixF>& data,
                 const DescriptorMatrixF& centres,
                 const Eigen::VectorXf& centre_norms,
                 Eigen::Index begin,
                 Eigen::Index end,
                 int* labels,
                 float* squared_distances) {
  Eigen::MatrixXf dots;
  for (Eigen::Index first = begin; first < end; first += kBlockRows) {
    const Eigen::Index rows = std::min(kBlockRows, end - first);
    const auto block = data.middleRows(first, rows);
    dots.noalias() = block * centres.transpose();
    for (Eigen::Index i = 0; i < rows; ++i) {
      // |x - c|^2 = |x|^2 - 2 x.c + |c|^2; |x|^2 is the same for every centre.
      int best = 0;
      float best_value = std::numeric_limits<float>::infinity();
      for (Eigen::Index c = 0; c < centres.rows(); ++c) {
        const float value = centre_norms[c] - 2.0f * dots(i, c);
        if (value < best_value) {
          best_value = value;
          best = static_cast<int>(c);
        }
      }
      labels[first + i] = best;
      if (squared_distances != nullptr) {
        squared_distances[first + i] = std::max(0.0f, best_value + block.row(i).squaredNorm());
      }
    }
  }
}

// Uniform double in [0, 1) from the top 53 bits: portable, unlike std::uniform_real_distribution.
double Uniform(std::mt19937_64* rng) { return static_cast<double>((*rng)() >> 11) * 0x1.0p-53; }

// k-means++ seeding: each next centre drawn with probability proportional to the squared
// distance to the nearest centre chosen so far.
DescriptorMatrixF SeedPlusPlus(const DescriptorMatrixF& data, int k, std::mt19937_64* rng) {
  const Eigen::Index n = data.rows();
  DescriptorMatrixF centres(k, 128);
  Eigen::Index chosen = std::min<Eigen::Index>(n - 1, static_cast<Eigen::Index>(Uniform(rng) * n));
  centres.row(0) = data.row(chosen);
  Eigen::VectorXd nearest =
      (data.rowwise() - centres.row(0)).rowwise().squaredNorm().cast<double>();
  for (int c = 1; c < k; ++c) {
    const double total = nearest.sum();
    if (total > 0.0) {
      const double target = Uniform(rng) * total;
      double cumulative = 0.0;
      chosen = n - 1;
      for (Eigen::Index i = 0; i < n; ++i) {
        cumulative += nearest[i];
        if (cumulative > target && nearest[i] > 0.0) {
          chosen = i;
          break;
        }
      }
    } else {
      // Fewer distinct points than centres: duplicates are harmless (their clusters stay empty
      // and are re-seeded).
      chosen = std::min<Eigen::Index>(n - 1, static_cast<Eigen::Index>(Uniform(rng) * n));
    }
    centres.row(c) = data.row(chosen);
    nearest =
        nearest.cwiseMin((data.rowwise() - centres.row(c)).rowwise().squaredNorm().cast<double>());
  }
  return centres;
}

}  // namespace

void AssignNearest(const Eigen::Ref<const DescriptorMatrixF>& data,
                   const DescriptorMatrixF& centres,
                   bool parallel,
                   std::vector<int>* labels,
                   std::vector<float>* squared_distances) {
  const Eigen::Index n = data.rows();
  labels->resize(n);
  float* distances = nullptr;
  if (squared_distances != nullptr) {
    squared_distances->resize(n);
    distances = squared_distances->data();
  }
  const Eigen::VectorXf centre_norms = centres.rowwise().squaredNorm();
  int num_threads = 1;
  if (parallel && n >= kMinParallelRows) {
    num_threads = static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 16u));
  }
  if (num_threads == 1) {
    AssignRange(data, centres, centre_norms, 0, n, labels->data(), distances);
    return;
  }
  std::vector<std::thread> threads;
  for (int t = 0; t < num_threads; ++t) {
    const Eigen::Index begin = n * t / num_threads;
    const Eigen::Index end = n * (t + 1) / num_threads;
    threads.emplace_back([&, begin, end] {
      AssignRange(data, centres, centre_norms, begin, end, labels->data(), distances);
    });
  }
  for (std::thread& thread : threads) thread.join();
}

DescriptorMatrixF KMeans(const DescriptorMatrixF& data, int k, uint64_t seed, int max_iterations) {
  EPILOC_CHECK(k >= 1 && data.rows() >= k, "k-means: {} points for {} centres", data.rows(), k);
  std::mt19937_64 rng(seed);
  DescriptorMatrixF centres = SeedPlusPlus(data, k, &rng);
  std::vector<int> labels(data.rows(), -1);
  std::vector<int> previous;
  std::vector<float> distances;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    previous.swap(labels);
    AssignNearest(data, centres, /*parallel=*/true, &labels, &distances);
    if (labels == previous) break;

    // Means in double, summed in row order: deterministic whatever the thread count above.
    Eigen::Matrix<double, Eigen::Dynamic, 128, Eigen::RowMajor> sums =
        Eigen::Matrix<double, Eigen::Dynamic, 128, Eigen::RowMajor>::Zero(k, 128);
    std::vector<int64_t> counts(k, 0);
    for (Eigen::Index i = 0; i < data.rows(); ++i) {
      sums.row(labels[i]) += data.row(i).cast<double>();
      ++counts[labels[i]];
    }
    for (int c = 0; c < k; ++c) {
      if (counts[c] > 0) {
        centres.row(c) = (sums.row(c) / static_cast<double>(counts[c])).cast<float>();
        continue;
      }
      const auto farthest = std::max_element(distances.begin(), distances.end());
      const Eigen::Index i = farthest - distances.begin();
      centres.row(c) = data.row(i);
      *farthest = 0.0f;  // not taken twice
      labels[i] = -1;    // forces another iteration
    }
  }
  return centres;
}

}  // namespace internal
}  // namespace epiloc
