// Matching one query frame against a whole window of database frames with one search: the RootSIFT
// descriptors of the window's frames live in one seeded kd-tree forest (KdForest: FLANN's
// algorithm, Muja & Lowe), updated incrementally as the window slides along the route, and each
// query descriptor is searched once for its K nearest database descriptors, which are then split by
// database frame for Lowe's ratio test. It replaces one kd-tree search per (query, database) pair
// with one per query frame.
#pragma once

#include <functional>
#include <memory>
#include <unordered_map>
#include <vector>

#include "epiloc/feature/types.h"

namespace epiloc {

struct WindowMatcherOptions {
  // Randomised kd-trees in the forest. The window is rebuilt every few query frames, so
  // build time counts: 2 trees cost ~12 % less per frame than 4 at the same accuracy (KITTI
  // development scenario, README).
  int num_trees = 2;
  // Points per leaf of the trees (KdForest's leaf_size): buckets of 8 reach the recall of
  // single-point leaves at twice the checks in half the time.
  int leaf_size = 8;
  // Neighbours K searched per query descriptor over the whole window (capped at the number of
  // indexed descriptors); about twice the number of window frames, so that most frames holding
  // a descriptor's true match get their best and second best among the K.
  int max_neighbors = 24;
  // The index is rebuilt from scratch when removed descriptors (still in the trees, skipped by
  // the search) exceed this fraction of all the descriptors it holds, or when it holds more than
  // twice as many as at its last build (incremental insertions unbalance the trees).
  double rebuild_fraction = 0.5;
  // With this, SetWindow only updates the index incrementally (it builds one only when there is
  // none) and the owner rebuilds it with Rebuild() when RebuildDue() says so, between searches:
  // off the critical path of a streaming caller (Localizer::Maintain).
  bool defer_rebuilds = false;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// One correspondence between the query frame and one database frame. Rows are rows of the
// descriptor matrices as given (the strongest-first prefixes): `query_row` of the query frame's
// descriptors passed to Match(), `db_row` of the database frame's descriptors returned by the
// loader passed to SetWindow(). (Unlike FeatureMatch, whose index_a is the indexed set: here the
// indexed set is the database window and the searched set the query.)
struct WindowMatch {
  int query_row = -1;
  int db_row = -1;
  float distance = 0.0f;  // RootSIFT L2 distance
};

// Usage, per query frame: SetWindow(window, load), then Match(query_descriptors, ...).
//
// Thread-safety: Match() is const and may run concurrently with other Match() calls; SetWindow()
// must not run concurrently with anything else on the same object. The matcher owns copies of
// the descriptors (as RootSIFT) and keeps no reference to the caller's data.
class WindowMatcher {
 public:
  // Loads the descriptors of one database frame (by database index), strongest first with the
  // caller's feature limit already applied. Must not return null.
  using LoadFn = std::function<std::shared_ptr<const FeatureDescriptors>(int db_index)>;

  explicit WindowMatcher(const WindowMatcherOptions& options = WindowMatcherOptions());
  ~WindowMatcher();
  WindowMatcher(const WindowMatcher&) = delete;
  WindowMatcher& operator=(const WindowMatcher&) = delete;

  // Makes the window exactly `db_indices` (any order, no duplicates, each >= 0): frames that left
  // are removed from the index, frames that entered are loaded with `load` and added. Frames
  // already in the window are not reloaded. Throws Error on a duplicate or negative index or a
  // null descriptor set; the matcher is then unchanged (frames are loaded before any change).
  void SetWindow(const std::vector<int>& db_indices, const LoadFn& load);

  // Whether the index has drifted far enough from a balanced one that the rule of
  // `rebuild_fraction` asks for a full build (only ever true with defer_rebuilds).
  bool RebuildDue() const;
  // Builds the index from scratch over the current window (releasing removed frames' rows).
  void Rebuild();

  // Database indices in the window, ascending.
  std::vector<int> Window() const;
  // Descriptors currently searched (all frames of the window).
  int NumDescriptors() const;
  // Times the index was built from scratch (diagnostics, tests).
  int NumRebuilds() const;

  // Matches the first `max_rows` rows of `query` (all if < 0) against the window:
  //   1. for each query row, its K nearest window descriptors, an approximate search that visits
  //      at least `checks` >= 1 leaves for the whole window (not per frame);
  //   2. per database frame, the frame's best and second best among the K, and Lowe's ratio test
  //      best < `ratio` * second best, `ratio` in (0, 1] (a frame with a single neighbour among
  //      the K is tested against the K-th distance, a lower bound of its second best);
  //   3. at most one match per database row: the closest query row wins.
  // The ratio test runs over the database frame's rows, DescriptorIndex's (query indexed) over
  // the query's: the two agree on most matches, not all. With 10 frames of 2000 descriptors and
  // leaves of 8, checks = 64 finds about 96 % of DescriptorIndex's matches (at its 64 checks per
  // pair) and 128 about 97 % (window_matcher_test). Every window frame has an entry (possibly
  // empty), its matches by ascending db_row. The search is split over `num_threads` >= 1 threads
  // (the result does not depend on it). Throws Error on an invalid argument.
  std::unordered_map<int, std::vector<WindowMatch>> Match(const FeatureDescriptors& query,
                                                          int max_rows,
                                                          double ratio,
                                                          int checks,
                                                          int num_threads = 1) const;

 private:
  struct Impl;

  WindowMatcherOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace epiloc
