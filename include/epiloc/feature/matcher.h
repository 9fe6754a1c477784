// Descriptor matching with a seeded kd-tree forest (KdForest: FLANN's algorithm, Muja & Lowe) on
// RootSIFT vectors, Lowe's ratio test and one-to-one matches.
#pragma once

#include <memory>
#include <vector>

#include "epiloc/feature/types.h"

namespace epiloc {

struct MatchOptions {
  // Lowe's ratio test: keep a match if best distance < ratio * second best.
  double ratio = 0.8;
  // Randomised kd-trees in the forest.
  int num_trees = 4;
  // Distances the forest computes per search: more is slower and closer to exact search.
  int num_checks = 64;

  void Check() const;
};

struct FeatureMatch {
  int index_a = -1;       // row in the indexed set (e.g. the query frame)
  int index_b = -1;       // row in the searched set (e.g. a database frame)
  float distance = 0.0f;  // RootSIFT L2 distance
};

// A kd-forest over one feature set (typically the query frame's), built once and searched with
// many others (the candidate database frames). Thread-safe for concurrent Match() calls.
class DescriptorIndex {
 public:
  // Indexes the first `max_rows` rows of `descriptors` (all if < 0).
  DescriptorIndex(const FeatureDescriptors& descriptors,
                  const MatchOptions& options,
                  int max_rows = -1);
  ~DescriptorIndex();
  DescriptorIndex(const DescriptorIndex&) = delete;
  DescriptorIndex& operator=(const DescriptorIndex&) = delete;

  int size() const { return num_rows_; }

  // Matches the first `max_rows` rows of `other` (all if < 0) against the index: for each row
  // the two nearest indexed rows, ratio test, then at most one match per indexed row (the
  // closest wins).
  std::vector<FeatureMatch> Match(const FeatureDescriptors& other, int max_rows = -1) const;

 private:
  struct Impl;
  MatchOptions options_;
  int num_rows_ = 0;
  std::unique_ptr<Impl> impl_;
};

// RootSIFT (Arandjelovic & Zisserman 2012): L1-normalise, square root; rows of 128 floats.
std::vector<float> ToRootSift(const FeatureDescriptors& descriptors, int num_rows);

}  // namespace epiloc
