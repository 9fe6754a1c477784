// Dynamic time warping of a query drive against the route database: Kyutoku et al., "Epipolar
// geometry-based ego-localization using an in-vehicle monocular camera", sec. 3.2, methods
// "DTW (fixed)" (first and last correspondence given) and "DTW (free)" (only the first), plus a
// causal online variant with constant work per frame.
//
// Query rows i = 0..N-1 are in time order, database (DB) frames j = 0..M-1 in route order (along-
// route distance s increasing). A path assigns each row one DB frame j(i).
//
// Step pattern: j(i) - j(i-1) = k with k in [0, max_step]. Consequences:
//   - a query slower than the database drive repeats frames (k = 0 on some rows), a stopped query
//     repeats one frame for as long as it stands;
//   - a query up to max_step times faster (in DB frames per query frame) skips frames;
//   - a query moving backwards along the route (reversing, or a drive in the opposite direction)
//     is not supported: the path is non-decreasing.
// Each step costs nothing by itself; the path cost is the sum of its cells' costs (a cell without
// evidence costs `missing_cost`) plus `step_penalty` * |k(i) - k(i-1)| per row from row 2 on.
// With step_penalty = 0 (default) this is the paper's plain DTW; a positive penalty prefers a
// constant speed, which also places rows without evidence by interpolation instead of arbitrarily
// among equal-cost cells. To support the penalty the state of a cell is (j, k = step into j).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace epiloc {

struct DtwOptions {
  // Most DB frames a row may advance past the previous row's match (steps 0..max_step), 1..100.
  int max_step = 4;
  // Cost of a cell with no evidence (not evaluated or failed), >= 0. With costs normalised to
  // [0, 1] per row, 1 lets the path cross rows that could not be matched without preferring them.
  double missing_cost = 1.0;
  // Cost per unit change of the step between consecutive rows, |k(i) - k(i-1)|, >= 0; 0 = the
  // paper's plain DTW.
  double step_penalty = 0.0;
  // Half-width of the search window in DB frames, >= 0. Online: frames kept on either side of the
  // current best. Offline: frames considered beyond a row's first and last evaluated cell.
  int band = 30;

  void Check() const;
};

// The evaluated cells of an N x M cost matrix, stored per row sorted by j: memory O(entries).
class SparseCostMatrix {
 public:
  using Entry = std::pair<int, double>;  // (DB frame j, cost)

  // num_query >= 0 rows, num_db >= 1 DB frames.
  SparseCostMatrix(int num_query, int num_db);

  int num_query() const { return static_cast<int>(rows_.size()); }
  int num_db() const { return num_db_; }
  int64_t num_entries() const { return num_entries_; }

  // Sets (or overwrites) the cost of cell (i, j); cost finite and >= 0 (small = close). Throws
  // Error on an index out of range or a bad cost. Amortised O(1) when a row is filled in
  // increasing j.
  void Set(int i, int j, double cost);
  // The cost of cell (i, j), none if it was not set.
  std::optional<double> Get(int i, int j) const;
  // The cells of row i, sorted by j.
  const std::vector<Entry>& Row(int i) const;

 private:
  int num_db_;
  std::vector<std::vector<Entry>> rows_;
  int64_t num_entries_ = 0;
};

struct DtwResult {
  bool valid = false;
  std::string failure;         // why not valid: "no query rows", "end before start", ...
  std::vector<int> db_index;   // per query row the matched DB frame j(i)
  std::vector<bool> evidence;  // per row: the matched cell had a real cost (not missing)
  double total_cost = 0.0;     // sum of the path's cell costs plus its step penalties
  int64_t num_cells = 0;       // DP cells visited (sum of the row window widths): work and memory
};

// DTW (fixed): j(0) = start_db, j(N-1) = end_db. Each row is searched in the window reachable
// from the previous row's window, able to reach end_db in time, and cut to the row's evaluated
// cells +- options.band (a row without evaluated cells keeps the whole reachable range). Work
// O(sum of window widths * max_step), memory O(sum of window widths * max_step) bytes. Invalid
// when no path exists (end_db < start_db, end_db - start_db > max_step * (N - 1), no rows).
// Throws Error if start_db or end_db is outside [0, M).
DtwResult AlignFixed(const SparseCostMatrix& costs,
                     int start_db,
                     int end_db,
                     const DtwOptions& options);

// DTW (free): j(0) = start_db, the last row's match is the argmin of its accumulated cost (ties:
// the smaller j). Windows and cost as AlignFixed.
DtwResult AlignFree(const SparseCostMatrix& costs, int start_db, const DtwOptions& options);

// Causal DTW, one query row at a time: keeps the accumulated cost only over a window of DB frames
// around the current best (at most 2 * band + 1 frames), advances it by the step pattern above,
// subtracts the minimum so it does not grow, and reports the argmin. Work per row
// O((band + max_step) * max_step + row entries), independent of num_db. The estimate is the end
// of the best path so far (a filter, not a smoother): unlike the offline path it may move back.
class OnlineDtw {
 public:
  // The first row pushed is aligned with start_db (as AlignFree's j(0)). Throws Error unless
  // 0 <= start_db < num_db and options.Check() passes.
  OnlineDtw(int num_db, int start_db, const DtwOptions& options);

  // Adds the next query row, given its evaluated cells (j, cost) in any order (cells outside the
  // window are ignored), and returns the current best j. Ties go to the smallest move from the
  // previous best (forward before backward). Throws Error on j outside [0, num_db) or a bad cost.
  int Push(const std::vector<std::pair<int, double>>& row_costs);

  // The best j after the last Push (start_db before the first).
  int current() const { return current_; }
  // Whether the last pushed row had a cost at current().
  bool evidence() const { return evidence_; }
  // Rows pushed since construction or the last Reset.
  int num_rows() const { return num_rows_; }

  // Re-anchors after a recovery (the caller's retrieval found a new position): forgets the
  // accumulated cost; the next row pushed is aligned with start_db.
  void Reset(int start_db);

 private:
  DtwOptions options_;
  int num_db_;
  int start_db_;
  int current_;
  bool evidence_ = false;
  int num_rows_ = 0;
  int window_lo_ = 0;  // first DB frame of the window
  int window_width_ = 0;
  std::vector<double> acc_;  // window_width_ x (max_step + 1): accumulated cost per (j, k)
  std::vector<double> next_, row_cost_, relaxed_;
  std::vector<uint8_t> relaxed_arg_;
};

}  // namespace epiloc
