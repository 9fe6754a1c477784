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
// compared at most once per search.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace epiloc {

class KdForest {
 public:
  static constexpr int kDim = 128;

  // `num_trees` >= 1; `seed` fixes every random choice of Build().
  explicit KdForest(int num_trees = 4, uint32_t seed = 20090101);

  // Replaces the forest with one over `num_rows` rows of kDim floats starting at `rows`. Point ids
  // are 0..num_rows-1. The rows are referenced, not copied: they must outlive the forest's use.
  void Build(const float* rows, size_t num_rows);

  // Inserts rows one by one into every tree (FLANN's addPoints without rebuild): ids continue
  // from size(). Trees lose balance as points are added: rebuild when they have grown much.
  void Add(const float* rows, size_t num_rows);

  // Marks a point removed: searches skip it; it keeps its id and its place in the trees.
  void Remove(size_t id);

  size_t size() const { return points_.size(); }  // ids handed out, removed ones included
  size_t num_removed() const { return num_removed_; }

  // The k nearest live points of each of `num_queries` rows at `queries`, as ids and squared L2
  // distances, nearest first, into k-column arrays (missing neighbours: id SIZE_MAX, distance
  // +inf). Each search computes at most max(checks, k) distances (fewer when the trees run out).
  // Const and safe to call from several threads at once.
  void Search(const float* queries,
              size_t num_queries,
              int k,
              int checks,
              size_t* ids,
              float* distances) const;

 private:
  // Inner nodes only: a child that is a single point is stored in the parent as ~id (negative),
  // so reaching a leaf costs no node load (the search is bound by memory latency, and each of its
  // `checks` ends at a leaf). 16 bytes: four nodes per cache line.
  struct Node {
    int child[2] = {-1, -1};  // >= 0: inner node index; < 0: leaf ~id
    int divfeat = 0;
    float divval = 0.0f;
  };
  struct Tree {
    std::vector<Node> nodes;
    int root = 0;  // as a child; meaningful when has_root
    bool has_root = false;
  };

  // Returns the subtree as a child value (inner node index, or ~id for a single point).
  int Divide(Tree& tree, uint32_t* ids, int count, uint64_t& rng);
  void Insert(Tree& tree, uint32_t id);

  int num_trees_;
  uint32_t seed_;
  std::vector<const float*> points_;
  std::vector<uint8_t> removed_;
  size_t num_removed_ = 0;
  std::vector<Tree> trees_;
};

}  // namespace epiloc
