#include "epiloc/feature/kd_forest.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr int kDim = KdForest::kDim;

// Points near a low-dimensional subspace, as descriptors are (their intrinsic dimension is far
// below 128): an 8-dimensional latent position per point, mapped linearly into 128 dimensions,
// plus a little noise in all of them, in RootSIFT's range (components in [0, 0.4]). Seeded: the
// same rows for the same seed.
std::vector<float> LowDimensionalRows(size_t num_rows, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.003f);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  std::mt19937 basis_rng(99);  // one subspace for every call: queries and rows share it
  std::vector<float> basis(8 * kDim);
  for (float& b : basis) b = 0.05f * uniform(basis_rng);
  std::vector<float> rows(num_rows * kDim);
  for (size_t i = 0; i < num_rows; ++i) {
    float latent[8];
    for (float& x : latent) x = uniform(rng);
    for (int d = 0; d < kDim; ++d) {
      float v = noise(rng);
      for (int j = 0; j < 8; ++j) v += latent[j] * basis[j * kDim + d];
      rows[i * kDim + d] = std::max(v, 0.0f);
    }
  }
  return rows;
}

struct Neighbours {
  std::vector<size_t> ids;
  std::vector<float> distances;
};

// The forest's 8-bit copy of a component.
float Quantized(float x) {
  return std::min(std::round(std::max(x, 0.0f) * KdForest::kQuantizationScale), 255.0f);
}

// Exact neighbours between the quantised rows, distances in the rows' units; ties by id.
Neighbours BruteForce(const std::vector<float>& rows,
                      const std::vector<bool>& removed,
                      const float* query,
                      int k) {
  std::vector<std::pair<float, size_t>> all;
  for (size_t i = 0; i < rows.size() / kDim; ++i) {
    if (removed[i]) continue;
    float d = 0;
    for (int j = 0; j < kDim; ++j) {
      const float diff = Quantized(rows[i * kDim + j]) - Quantized(query[j]);
      d += diff * diff;
    }
    all.emplace_back(d / (KdForest::kQuantizationScale * KdForest::kQuantizationScale), i);
  }
  std::sort(all.begin(), all.end());
  Neighbours out;
  for (int i = 0; i < k && i < static_cast<int>(all.size()); ++i) {
    out.distances.push_back(all[i].first);
    out.ids.push_back(all[i].second);
  }
  return out;
}

// Every behaviour holds for FLANN's single-point leaves and for buckets (the window matcher's 8).
class KdForestLeaves : public ::testing::TestWithParam<int> {
 protected:
  int leaf_size() const { return GetParam(); }
};

TEST_P(KdForestLeaves, ExhaustiveBudgetGivesTheExactNeighbours) {
  const std::vector<float> rows = LowDimensionalRows(600, 1);
  const std::vector<float> queries = LowDimensionalRows(40, 2);
  KdForest forest(4, KdForest::kDefaultSeed, leaf_size());
  forest.Build(rows.data(), 600);
  const int k = 5;
  std::vector<size_t> ids(40 * k);
  std::vector<float> distances(40 * k);
  forest.Search(queries.data(), 40, k, 600, ids.data(), distances.data());
  const std::vector<bool> removed(600, false);
  for (int q = 0; q < 40; ++q) {
    const Neighbours truth = BruteForce(rows, removed, queries.data() + q * kDim, k + 1);
    for (int i = 0; i < k; ++i) {
      EXPECT_FLOAT_EQ(distances[q * k + i], truth.distances[i]) << "query " << q << " #" << i;
      // Equal distances may come in either order.
      const bool tied = (i > 0 && truth.distances[i - 1] == truth.distances[i]) ||
                        truth.distances[i + 1] == truth.distances[i];
      if (!tied) {
        EXPECT_EQ(ids[q * k + i], truth.ids[i]) << "query " << q << " #" << i;
      }
    }
  }
}

TEST_P(KdForestLeaves, SameRowsGiveTheSameAnswersEveryTime) {
  const std::vector<float> rows = LowDimensionalRows(3000, 3);
  const std::vector<float> queries = LowDimensionalRows(200, 4);
  auto run = [&](uint32_t seed) {
    KdForest forest(4, seed, leaf_size());
    forest.Build(rows.data(), 3000);
    std::vector<size_t> ids(200 * 2);
    std::vector<float> distances(200 * 2);
    // A small budget: the answer depends on the trees' shapes.
    forest.Search(queries.data(), 200, 2, 8, ids.data(), distances.data());
    return ids;
  };
  const std::vector<size_t> first = run(7);
  EXPECT_EQ(run(7), first);
  EXPECT_EQ(run(7), first);
  EXPECT_NE(run(8), first) << "the seed changes nothing: are the trees random at all?";
}

TEST_P(KdForestLeaves, ApproximateSearchFindsMostTrueNeighbours) {
  const std::vector<float> rows = LowDimensionalRows(5000, 5);
  const std::vector<float> queries = LowDimensionalRows(300, 6);
  KdForest forest(4, KdForest::kDefaultSeed, leaf_size());
  forest.Build(rows.data(), 5000);
  std::vector<size_t> ids(300);
  std::vector<float> distances(300);
  forest.Search(queries.data(), 300, 1, 64, ids.data(), distances.data());
  const std::vector<bool> removed(5000, false);
  int hits = 0;
  for (int q = 0; q < 300; ++q) {
    hits += ids[q] == BruteForce(rows, removed, queries.data() + q * kDim, 1).ids[0];
  }
  // 64 of 5000 points compared: far from exhaustive, yet most nearest neighbours are found.
  EXPECT_GT(hits, 300 / 2);
  EXPECT_LT(hits, 300) << "64 checks found every neighbour: the budget is not applied";
}

TEST_P(KdForestLeaves, AddedPointsAreFoundAndRemovedOnesNot) {
  const std::vector<float> rows = LowDimensionalRows(800, 7);
  KdForest forest(2, KdForest::kDefaultSeed, leaf_size());
  forest.Build(rows.data(), 300);
  forest.Add(rows.data() + 300 * kDim, 500);
  EXPECT_EQ(forest.size(), 800u);
  std::vector<bool> removed(800, false);
  for (size_t id = 0; id < 800; id += 3) {
    forest.Remove(id);
    removed[id] = true;
  }
  forest.Remove(0);  // twice: no effect
  EXPECT_EQ(forest.num_removed(), 267u);
  const std::vector<float> queries = LowDimensionalRows(30, 8);
  const int k = 3;
  std::vector<size_t> ids(30 * k);
  std::vector<float> distances(30 * k);
  forest.Search(queries.data(), 30, k, 800, ids.data(), distances.data());
  for (int q = 0; q < 30; ++q) {
    const Neighbours truth = BruteForce(rows, removed, queries.data() + q * kDim, k);
    for (int i = 0; i < k; ++i) {
      EXPECT_FLOAT_EQ(distances[q * k + i], truth.distances[i]) << q << " " << i;
      if (!removed[ids[q * k + i]]) continue;
      ADD_FAILURE() << "query " << q << " found removed point " << ids[q * k + i];
    }
  }
}

TEST_P(KdForestLeaves, DistancesAreTheRowsToTheQuantisationsResolution) {
  // Two rows a known distance apart, then components beyond the 8-bit range (clamped: a row
  // of 0.6 is stored as one of 255/512).
  std::vector<float> rows(3 * kDim, 0.1f);
  for (int d = 0; d < kDim; d += 2) rows[kDim + d] = 0.2f;   // 64 components 0.1 off
  for (int d = 0; d < kDim; ++d) rows[2 * kDim + d] = 0.6f;  // clamped
  KdForest forest(2, KdForest::kDefaultSeed, leaf_size());
  forest.Build(rows.data(), 3);
  const std::vector<float> query(kDim, 0.1f);
  std::vector<size_t> ids(3);
  std::vector<float> distances(3);
  forest.Search(query.data(), 1, 3, 64, ids.data(), distances.data());
  EXPECT_EQ(ids[0], 0u);
  EXPECT_EQ(ids[1], 1u);
  EXPECT_EQ(distances[0], 0.0f);
  // 0.1 and 0.2 are stored as 51/512 and 102/512: off by less than half a step each.
  EXPECT_NEAR(distances[1], 64 * 0.1f * 0.1f, 64 * 2 * 0.1f / 512);
  EXPECT_FLOAT_EQ(distances[1], 64 * (51.0f / 512) * (51.0f / 512));
  const float clamped = (255.0f - 51.0f) / 512;
  EXPECT_FLOAT_EQ(distances[2], kDim * clamped * clamped);
}

TEST_P(KdForestLeaves, FewerPointsThanNeighboursAndDuplicates) {
  std::vector<float> rows(4 * kDim, 0.25f);  // four identical rows
  KdForest forest(3, KdForest::kDefaultSeed, leaf_size());
  forest.Build(rows.data(), 4);
  const std::vector<float> query(kDim, 0.25f);
  std::vector<size_t> ids(6);
  std::vector<float> distances(6);
  forest.Search(query.data(), 1, 6, 64, ids.data(), distances.data());
  std::vector<size_t> found(ids.begin(), ids.begin() + 4);
  std::sort(found.begin(), found.end());
  EXPECT_EQ(found, (std::vector<size_t>{0, 1, 2, 3}));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(distances[i], 0.0f);
  EXPECT_EQ(ids[4], std::numeric_limits<size_t>::max());
  EXPECT_TRUE(std::isinf(distances[5]));

  KdForest empty(1, KdForest::kDefaultSeed, leaf_size());
  empty.Build(rows.data(), 0);
  empty.Search(query.data(), 1, 2, 8, ids.data(), distances.data());
  EXPECT_EQ(ids[0], std::numeric_limits<size_t>::max());
  EXPECT_THROW(KdForest(0), Error);
  EXPECT_THROW(KdForest(1, KdForest::kDefaultSeed, 0), Error);
  EXPECT_THROW(empty.Remove(0), Error);
  EXPECT_THROW(forest.Search(query.data(), 1, 0, 8, ids.data(), distances.data()), Error);
}

// Many identical rows added one by one: a leaf of equal points cannot be split, and grows.
TEST_P(KdForestLeaves, AddingManyEqualRowsKeepsThemAll) {
  std::vector<float> rows(50 * kDim, 0.25f);
  KdForest forest(2, KdForest::kDefaultSeed, leaf_size());
  forest.Build(rows.data(), 1);
  forest.Add(rows.data() + kDim, 49);
  const std::vector<float> query(kDim, 0.25f);
  std::vector<size_t> ids(50);
  std::vector<float> distances(50);
  forest.Search(query.data(), 1, 50, 50, ids.data(), distances.data());
  std::sort(ids.begin(), ids.end());
  for (size_t i = 0; i < 50; ++i) EXPECT_EQ(ids[i], i);
}

INSTANTIATE_TEST_SUITE_P(LeafSizes,
                         KdForestLeaves,
                         ::testing::Values(1, 8),
                         [](const ::testing::TestParamInfo<int>& info) {
                           return "leaf" + std::to_string(info.param);
                         });

}  // namespace
}  // namespace epiloc
