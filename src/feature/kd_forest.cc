#include "epiloc/feature/kd_forest.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <functional>
#include <limits>
#include <numeric>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// FLANN's constants: the mean and variance of a node are estimated from its first 100 points, and
// the split dimension is drawn among the 5 of highest variance.
constexpr int kSampleMean = 100;
constexpr int kRandomDims = 5;

// SplitMix64 (Steele et al. 2014): small, fast, and the same sequence on every platform, unlike
// the standard distributions, whose algorithms are left to the library.
uint64_t NextRandom(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

int RandomBelow(uint64_t& state, int n) {
  return static_cast<int>(NextRandom(state) % static_cast<uint64_t>(n));
}

// A row in 8 bits: round(x * kQuantizationScale), clamped to [0, 255].
void Quantize(const float* row, uint8_t* out) {
  for (int d = 0; d < KdForest::kDim; ++d) {
    const float v = row[d] * KdForest::kQuantizationScale;  // NaN and negatives: 0
    out[d] = v > 0.0f ? static_cast<uint8_t>(std::min(v, 255.0f) + 0.5f) : 0;  // rounded
  }
}

// Squared L2 distance between two stored rows, abandoned (returning a partial sum above `bound`)
// once it exceeds `bound`: most candidates of a search are farther than the current k-th
// neighbour. In integer units of the quantisation (exact: at most 128 * 255^2 < 2^24).
float SquaredDistance(const uint8_t* a, const uint8_t* b, float bound) {
  constexpr int kBlock = 32;
  int32_t sum = 0;
  for (int offset = 0; offset < KdForest::kDim; offset += kBlock) {
    int32_t block = 0;
    for (int d = offset; d < offset + kBlock; ++d) {
      const int32_t diff = static_cast<int32_t>(a[d]) - static_cast<int32_t>(b[d]);
      block += diff * diff;
    }
    sum += block;
    if (static_cast<float>(sum) > bound) break;
  }
  return static_cast<float>(sum);
}

}  // namespace

KdForest::KdForest(int num_trees, uint32_t seed, int leaf_size)
    : num_trees_(num_trees), seed_(seed), leaf_size_(leaf_size) {
  EPILOC_CHECK(num_trees >= 1, "kd-forest: num_trees must be >= 1, got {}", num_trees);
  EPILOC_CHECK(leaf_size >= 1, "kd-forest: leaf_size must be >= 1, got {}", leaf_size);
}

void KdForest::Build(const float* rows, size_t num_rows) {
  EPILOC_CHECK(num_rows < static_cast<size_t>(std::numeric_limits<int>::max()),
               "kd-forest: {} rows are too many for one index", num_rows);
  data_.resize(num_rows * kDim);
  for (size_t i = 0; i < num_rows; ++i) Quantize(rows + i * kDim, data_.data() + i * kDim);
  removed_.assign(num_rows, 0);
  num_removed_ = 0;
  trees_.assign(num_trees_, Tree());
  if (num_rows == 0) return;
  uint64_t rng = seed_;
  std::vector<uint32_t> ids(num_rows);
  std::iota(ids.begin(), ids.end(), 0u);
  for (Tree& tree : trees_) {
    // Fisher-Yates: each tree samples its node means from another random subset.
    for (size_t i = num_rows - 1; i > 0; --i) {
      std::swap(ids[i], ids[RandomBelow(rng, static_cast<int>(i + 1))]);
    }
    tree.nodes.reserve(2 * num_rows / leaf_size_ + 1);
    tree.buckets.reserve(2 * num_rows / leaf_size_ + 1);
    tree.root = Divide(tree, ids.data(), static_cast<int>(num_rows), rng);
    tree.has_root = true;
  }
}

int KdForest::Divide(Tree& tree, uint32_t* ids, int count, uint64_t& rng) {
  if (count <= leaf_size_) {
    tree.buckets.emplace_back(ids, ids + count);
    return ~static_cast<int>(tree.buckets.size() - 1);
  }
  const int index = static_cast<int>(tree.nodes.size());
  tree.nodes.emplace_back();
  // Mean and variance per dimension over a sample of the node's points.
  const int sample = std::min(count, kSampleMean);
  std::array<float, kDim> mean{}, var{};
  for (int i = 0; i < sample; ++i) {
    const uint8_t* p = Row(ids[i]);
    for (int d = 0; d < kDim; ++d) mean[d] += static_cast<float>(p[d]);
  }
  for (int d = 0; d < kDim; ++d) mean[d] /= static_cast<float>(sample);
  for (int i = 0; i < sample; ++i) {
    const uint8_t* p = Row(ids[i]);
    for (int d = 0; d < kDim; ++d) {
      const float diff = static_cast<float>(p[d]) - mean[d];
      var[d] += diff * diff;
    }
  }
  // One of the dimensions of highest variance, at random: the trees differ where it matters least.
  // The kRandomDims highest, in that order (ties: lower dimension first), by insertion in one
  // pass: a partial sort of all 128 cost as much as the rest of the node.
  std::array<int, kRandomDims> top;
  std::array<float, kRandomDims> top_var;
  int num_top = 0;
  for (int d = 0; d < kDim; ++d) {
    const float v = var[d];
    if (num_top == kRandomDims && !(v > top_var[kRandomDims - 1])) continue;
    int pos = num_top;
    while (pos > 0 && v > top_var[pos - 1]) --pos;  // d > top[*]: ties stay behind
    for (int i = std::min(num_top, kRandomDims - 1); i > pos; --i) {
      top[i] = top[i - 1];
      top_var[i] = top_var[i - 1];
    }
    top[pos] = d;
    top_var[pos] = v;
    num_top = std::min(num_top + 1, kRandomDims);
  }
  const int divfeat = top[RandomBelow(rng, kRandomDims)];
  const float divval = mean[divfeat];
  // Split at the mean; ties go to whichever side balances the tree (FLANN's planeSplit).
  uint32_t* end = ids + count;
  uint32_t* less = std::partition(ids, end, [&](uint32_t id) { return Row(id)[divfeat] < divval; });
  uint32_t* less_equal =
      std::partition(less, end, [&](uint32_t id) { return Row(id)[divfeat] <= divval; });
  const int lim1 = static_cast<int>(less - ids), lim2 = static_cast<int>(less_equal - ids);
  int split = lim1 > count / 2 ? lim1 : lim2 < count / 2 ? lim2 : count / 2;
  if (lim1 == count || lim2 == 0) split = count / 2;  // all on one side: halve
  if (split == 0 || split == count) split = count / 2;

  const int left = Divide(tree, ids, split, rng);
  const int right = Divide(tree, ids + split, count - split, rng);
  Node& node = tree.nodes[index];
  node.child[0] = left;
  node.child[1] = right;
  node.divfeat = divfeat;
  node.divval = divval;
  return index;
}

void KdForest::Add(const float* rows, size_t num_rows) {
  EPILOC_CHECK(size() + num_rows < static_cast<size_t>(std::numeric_limits<int>::max()),
               "kd-forest: {} rows are too many for one index", size() + num_rows);
  if (trees_.empty()) trees_.assign(num_trees_, Tree());
  for (size_t i = 0; i < num_rows; ++i) {
    const uint32_t id = static_cast<uint32_t>(size());
    data_.resize(data_.size() + kDim);
    Quantize(rows + i * kDim, data_.data() + static_cast<size_t>(id) * kDim);
    removed_.push_back(0);
    for (Tree& tree : trees_) Insert(tree, id);
  }
}

void KdForest::Insert(Tree& tree, uint32_t id) {
  const uint8_t* p = Row(id);
  if (!tree.has_root) {
    tree.buckets.push_back({id});
    tree.root = ~static_cast<int>(tree.buckets.size() - 1);
    tree.has_root = true;
    return;
  }
  // Down to the leaf where p falls, remembering the slot that holds it.
  int* slot = &tree.root;
  while (*slot >= 0) {
    Node& node = tree.nodes[*slot];
    slot = &node.child[p[node.divfeat] < node.divval ? 0 : 1];
  }
  const int leaf = ~*slot;
  std::vector<uint32_t>& bucket = tree.buckets[leaf];
  bucket.push_back(id);
  // Single-point leaves stay single (FLANN's addPoints); buckets may grow to twice their size.
  const int max_leaf = leaf_size_ == 1 ? 1 : 2 * leaf_size_;
  if (static_cast<int>(bucket.size()) <= max_leaf) return;
  // A full leaf becomes a split at the mean of its points along their widest dimension.
  std::array<int, kDim> lo, hi;
  lo.fill(255);
  hi.fill(0);
  for (const uint32_t i : bucket) {
    const uint8_t* row = Row(i);
    for (int d = 0; d < kDim; ++d) {
      lo[d] = std::min<int>(lo[d], row[d]);
      hi[d] = std::max<int>(hi[d], row[d]);
    }
  }
  int divfeat = 0;
  for (int d = 1; d < kDim; ++d) {
    if (hi[d] - lo[d] > hi[divfeat] - lo[divfeat]) divfeat = d;
  }
  if (hi[divfeat] == lo[divfeat]) return;  // identical rows: the leaf grows
  float divval = 0.0f;
  for (const uint32_t i : bucket) divval += static_cast<float>(Row(i)[divfeat]);
  divval /= static_cast<float>(bucket.size());
  std::vector<uint32_t> right;
  const auto left_end = std::stable_partition(bucket.begin(), bucket.end(),
                                              [&](uint32_t i) { return Row(i)[divfeat] < divval; });
  right.assign(left_end, bucket.end());
  bucket.erase(left_end, bucket.end());
  Node node;
  node.child[0] = ~leaf;
  node.child[1] = ~static_cast<int>(tree.buckets.size());
  node.divfeat = divfeat;
  node.divval = divval;
  tree.buckets.push_back(std::move(right));  // `bucket` is not used after this
  // `slot` may point into `nodes`: compute the index before the vector grows.
  const int index = static_cast<int>(tree.nodes.size());
  *slot = index;
  tree.nodes.push_back(node);
}

void KdForest::Remove(size_t id) {
  EPILOC_CHECK(id < size(), "kd-forest: no point {} (size {})", id, size());
  if (!removed_[id]) {
    removed_[id] = 1;
    ++num_removed_;
  }
}

void KdForest::Search(const float* queries,
                      size_t num_queries,
                      int k,
                      int checks,
                      size_t* ids,
                      float* distances) const {
  EPILOC_CHECK(k >= 1, "kd-forest: k must be >= 1, got {}", k);
  EPILOC_CHECK(checks >= 1, "kd-forest: checks must be >= 1, got {}", checks);
  struct Branch {
    float mindist;
    int tree;
    int node;
    bool operator>(const Branch& other) const { return mindist > other.mindist; }
  };
  // A min-heap on mindist in a plain vector, emptied in O(1) after each search.
  std::vector<Branch> heap;
  const auto push = [&heap](const Branch& branch) {
    heap.push_back(branch);
    std::push_heap(heap.begin(), heap.end(), std::greater<Branch>());
  };
  std::vector<uint8_t> checked(size(), 0);
  std::array<uint8_t, kDim> q;
  // Distances are searched in quantisation units and reported in the rows' units.
  const float to_rows = 1.0f / (kQuantizationScale * kQuantizationScale);
  std::vector<uint32_t> touched;

  for (size_t qi = 0; qi < num_queries; ++qi) {
    Quantize(queries + qi * kDim, q.data());
    size_t* out_ids = ids + qi * k;
    float* out_d = distances + qi * k;
    std::fill(out_ids, out_ids + k, std::numeric_limits<size_t>::max());
    std::fill(out_d, out_d + k, std::numeric_limits<float>::infinity());
    int found = 0;
    int done = 0;
    // out_d[k-1] is the current k-th distance (infinite until k are found).
    // `n` is a child value: an inner node index, or ~bucket for a leaf.
    auto search_from = [&](int t, int n, float mindist) {
      const Tree& tree = trees_[t];
      while (true) {
        if (mindist > out_d[k - 1]) return;
        if (n < 0) {
          for (const uint32_t id : tree.buckets[~n]) {
            if (checked[id] || removed_[id]) continue;
            if (done >= checks && found == k) return;
            checked[id] = 1;
            touched.push_back(id);
            ++done;
            const float d = SquaredDistance(q.data(), Row(id), out_d[k - 1]);
            if (d >= out_d[k - 1]) continue;
            int pos = std::min(found, k - 1);
            while (pos > 0 && out_d[pos - 1] > d) {
              out_d[pos] = out_d[pos - 1];
              out_ids[pos] = out_ids[pos - 1];
              --pos;
            }
            out_d[pos] = d;
            out_ids[pos] = id;
            found = std::min(found + 1, k);
          }
          return;
        }
        const Node& node = tree.nodes[n];
        const float diff = static_cast<float>(q[node.divfeat]) - node.divval;
        const int near = node.child[diff < 0 ? 0 : 1];
        const int far = node.child[diff < 0 ? 1 : 0];
        const float far_dist = mindist + diff * diff;
        if (far_dist < out_d[k - 1]) push({far_dist, t, far});
        n = near;
      }
    };
    for (int t = 0; t < static_cast<int>(trees_.size()); ++t) {
      if (trees_[t].has_root) search_from(t, trees_[t].root, 0.0f);
    }
    while (!heap.empty() && (done < checks || found < k)) {
      std::pop_heap(heap.begin(), heap.end(), std::greater<Branch>());
      const Branch branch = heap.back();
      heap.pop_back();
      search_from(branch.tree, branch.node, branch.mindist);
    }
    for (int i = 0; i < found; ++i) out_d[i] *= to_rows;
    heap.clear();
    for (uint32_t id : touched) checked[id] = 0;
    touched.clear();
  }
}

}  // namespace epiloc
