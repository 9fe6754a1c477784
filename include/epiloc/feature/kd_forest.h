// A forest of randomised kd-trees over RootSIFT rows (128 floats) for approximate nearest-neighbour
// search: the algorithm of FLANN's KDTreeIndex (Silpa-Anan & Hartley 2008; Muja & Lowe 2009) with
// every random choice drawn from a seeded generator, so that the same rows inserted in the same
// order give the same trees and the same answers on every run and machine.
//
// Why not FLANN itself: FLANN 1.9 (Debian's libflann) shuffles the points of every tree with a
// std::random_device that cannot be seeded (flann/algorithms/kdtree_index.h), so two runs of the
// same localization differed by up to 0.8 m; its seedable indices (hierarchical k-means) build
// 5-10x slower on a window of 20 frames, and OpenCV's copy of FLANN has no incremental insertion
// or removal, which the sliding database window needs. The search is FLANN's: best-bin-first over
// all trees with one priority queue, a budget of `checks` distance computations, and each point
// compared at most once per search. Optionally (`leaf_size` > 1) a leaf holds a bucket of up to
// leaf_size points, as FLANN's single kd-tree and nanoflann do: a search's budget is spent on fewer
// descents and heap entries, and a bucket's rows are read one after another. Measured on 40,000
// KITTI RootSIFT rows (k = 24): leaves of 8 search 4x faster than single points at the same budget
// with 10-15 % less recall of the exact nearest neighbour, and at twice the budget reach about the
// same recall in half the time (leaves of 4 gain less, of 16 lose more recall).
//
// The forest keeps its own copy of the rows in 8 bits per component (x * 512, rounded, clamped
// to [0, 255]): a RootSIFT component is at most about 0.5, and the search is bound by memory
// traffic, which a quarter of the bytes per row cuts ~4x. The rounding moves a squared distance by
// about 1e-4 against typical nearest-neighbour distances of 0.1-0.5.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace epiloc {

class KdForest {
 public:
  static constexpr int kDim = 128;
  static constexpr float kQuantizationScale = 512.0f;

  // `num_trees` >= 1; `seed` fixes every random choice of Build(); `leaf_size` >= 1: points per
  // leaf of a built tree (Add() lets a leaf of more than one grow to twice that, then splits it).
  static constexpr uint32_t kDefaultSeed = 20090101;
  explicit KdForest(int num_trees = 4, uint32_t seed = kDefaultSeed, int leaf_size = 1);

  // Replaces the forest with one over `num_rows` rows of kDim floats starting at `rows`. Point ids
  // are 0..num_rows-1. The rows are copied (in 8 bits).
  void Build(const float* rows, size_t num_rows);

  // Inserts rows one by one into every tree (FLANN's addPoints without rebuild): ids continue
  // from size(). Trees lose balance as points are added: rebuild when they have grown much.
  void Add(const float* rows, size_t num_rows);

  // Marks a point removed: searches skip it; it keeps its id and its place in the trees.
  void Remove(size_t id);

  size_t size() const { return removed_.size(); }  // ids handed out, removed ones included
  size_t num_removed() const { return num_removed_; }

  // The k nearest live points of each of `num_queries` rows at `queries`, as ids and squared L2
  // distances between the quantised rows (in the rows' units), nearest first, into k-column arrays
  // (missing neighbours: id SIZE_MAX, distance +inf). Each search computes at most max(checks, k)
  // distances (fewer when the trees run out). Const and safe to call from several threads at once.
  void Search(const float* queries,
              size_t num_queries,
              int k,
              int checks,
              size_t* ids,
              float* distances) const;

 private:
  // Inner nodes; a child that is a leaf is stored in the parent as ~(bucket index) (negative).
  // 16 bytes: four nodes per cache line.
  struct Node {
    int child[2] = {-1, -1};  // >= 0: inner node index; < 0: leaf ~bucket
    int divfeat = 0;
    float divval = 0.0f;
  };
  struct Tree {
    std::vector<Node> nodes;
    std::vector<std::vector<uint32_t>> buckets;  // the leaves' point ids
    int root = 0;  // as a child; meaningful when has_root
    bool has_root = false;
  };

  // Returns the subtree as a child value (inner node index, or ~bucket for a leaf).
  int Divide(Tree& tree, uint32_t* ids, int count, uint64_t& rng);
  void Insert(Tree& tree, uint32_t id);

  int num_trees_;
  uint32_t seed_;
  int leaf_size_;
  const uint8_t* Row(size_t id) const { return data_.data() + id * kDim; }

  std::vector<uint8_t> data_;  // size() rows of kDim, quantised
  std::vector<uint8_t> removed_;
  size_t num_removed_ = 0;
  std::vector<Tree> trees_;
};

}  // namespace epiloc
