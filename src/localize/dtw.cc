#include "epiloc/localize/dtw.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxStep = 100;  // backpointers hold a step in one byte
constexpr int kMaxBand = 1000000;

// A contiguous range of DB frames [lo, lo + width).
struct Window {
  int lo = 0;
  int width = 0;
  int hi() const { return lo + width - 1; }
};

bool GoodCost(double cost) { return std::isfinite(cost) && cost >= 0.0; }

// For every cell of a row (states values each, state k = step into the cell): best(c, k) =
// min over k' of acc(c, k') + penalty * |k - k'|, the cheapest way to leave cell c with step k,
// and its argmin k'. An L1 distance transform in two passes, O(states) per cell; ties keep k' = k.
void Relax(const std::vector<double>& acc,
           int width,
           int states,
           double penalty,
           std::vector<double>* best,
           std::vector<uint8_t>* arg) {
  best->assign(acc.begin(), acc.begin() + static_cast<size_t>(width) * states);
  arg->resize(best->size());
  for (int c = 0; c < width; ++c) {
    double* b = best->data() + static_cast<size_t>(c) * states;
    uint8_t* a = arg->data() + static_cast<size_t>(c) * states;
    for (int k = 0; k < states; ++k) a[k] = static_cast<uint8_t>(k);
    for (int k = 1; k < states; ++k) {
      if (b[k - 1] + penalty < b[k]) {
        b[k] = b[k - 1] + penalty;
        a[k] = a[k - 1];
      }
    }
    for (int k = states - 2; k >= 0; --k) {
      if (b[k + 1] + penalty < b[k]) {
        b[k] = b[k + 1] + penalty;
        a[k] = a[k + 1];
      }
    }
  }
}

// One DP row over `window`: out(j, k) = cost(j) + best(j - k, k) with `best` the relaxed previous
// row over `prev`; back(j, k), if given, receives the previous cell's state.
void AdvanceRow(const std::vector<double>& best,
                const std::vector<uint8_t>& best_arg,
                Window prev,
                const std::vector<double>& cost,
                Window window,
                int states,
                std::vector<double>* out,
                uint8_t* back) {
  out->assign(static_cast<size_t>(window.width) * states, kInf);
  if (back) std::fill(back, back + out->size(), uint8_t{0});
  for (int c = 0; c < window.width; ++c) {
    const int j = window.lo + c;
    for (int k = 0; k < states; ++k) {
      const int p = j - k - prev.lo;
      if (p < 0) break;
      if (p >= prev.width) continue;
      const size_t from = static_cast<size_t>(p) * states + k;
      const size_t to = static_cast<size_t>(c) * states + k;
      (*out)[to] = cost[c] + best[from];
      if (back) back[to] = best_arg[from];
    }
  }
}

// The costs of row cells over `window`, missing cells at `missing_cost`.
void FillRowCost(const std::vector<SparseCostMatrix::Entry>& row,
                 Window window,
                 double missing_cost,
                 std::vector<double>* cost) {
  cost->assign(window.width, missing_cost);
  auto it = std::lower_bound(row.begin(), row.end(), window.lo,
                             [](const SparseCostMatrix::Entry& e, int j) { return e.first < j; });
  for (; it != row.end() && it->first <= window.hi(); ++it) {
    (*cost)[it->first - window.lo] = it->second;
  }
}

double MinState(const std::vector<double>& values, int c, int states, int* arg = nullptr) {
  const double* v = values.data() + static_cast<size_t>(c) * states;
  const int k = static_cast<int>(std::min_element(v, v + states) - v);
  if (arg) *arg = k;
  return v[k];
}

// DTW with j(0) = start_db and, if `end_db` is set, j(N-1) = *end_db.
DtwResult Align(const SparseCostMatrix& costs,
                int start_db,
                std::optional<int> end_db,
                const DtwOptions& options) {
  options.Check();
  const int n = costs.num_query();
  const int m = costs.num_db();
  const int max_step = options.max_step;
  EPILOC_CHECK(start_db >= 0 && start_db < m, "dtw: start_db {} outside [0, {})", start_db, m);
  if (end_db) {
    EPILOC_CHECK(*end_db >= 0 && *end_db < m, "dtw: end_db {} outside [0, {})", *end_db, m);
  }
  DtwResult result;
  if (n == 0) {
    result.failure = "no query rows";
    return result;
  }
  if (end_db && *end_db < start_db) {
    result.failure = fmt::format("end_db {} before start_db {}", *end_db, start_db);
    return result;
  }
  if (end_db && int64_t{*end_db} - start_db > int64_t{max_step} * (n - 1)) {
    result.failure =
        fmt::format("end_db {} not reachable from start_db {} in {} rows of max_step {}", *end_db,
                    start_db, n, max_step);
    return result;
  }

  const int states = max_step + 1;
  std::vector<Window> windows(n);
  std::vector<size_t> back_offset(n + 1, 0);  // row i's backpointers start at back[back_offset[i]]
  std::vector<uint8_t> back;
  std::vector<double> cost, best, next;
  std::vector<uint8_t> best_arg;

  windows[0] = {start_db, 1};
  FillRowCost(costs.Row(0), windows[0], options.missing_cost, &cost);
  // Row 0 has no step yet: every state starts equal, so the first step is free of penalty.
  std::vector<double> acc(states, cost[0]);
  result.num_cells = 1;
  for (int i = 1; i < n; ++i) {
    const Window prev = windows[i - 1];
    // Reachable from the previous window, and (fixed) still able to reach end_db in time. Both
    // bounds keep every cell of the window reachable and every window non-empty.
    int64_t lo = prev.lo;
    int64_t hi = std::min<int64_t>(int64_t{prev.hi()} + max_step, m - 1);
    if (end_db) {
      lo = std::max<int64_t>(lo, *end_db - int64_t{max_step} * (n - 1 - i));
      hi = std::min<int64_t>(hi, *end_db);
    }
    const auto& row = costs.Row(i);
    if (!row.empty()) {
      const int64_t evidence_lo = std::max<int64_t>(lo, int64_t{row.front().first} - options.band);
      const int64_t evidence_hi = std::min<int64_t>(hi, int64_t{row.back().first} + options.band);
      // Evaluated cells out of reach leave the row to the missing cost over its reachable range.
      if (evidence_lo <= evidence_hi) {
        lo = evidence_lo;
        hi = evidence_hi;
      }
    }
    windows[i] = {static_cast<int>(lo), static_cast<int>(hi - lo + 1)};
    result.num_cells += windows[i].width;

    Relax(acc, prev.width, states, options.step_penalty, &best, &best_arg);
    FillRowCost(row, windows[i], options.missing_cost, &cost);
    back.resize(back_offset[i] + static_cast<size_t>(windows[i].width) * states);
    AdvanceRow(best, best_arg, prev, cost, windows[i], states, &next, back.data() + back_offset[i]);
    back_offset[i + 1] = back.size();
    acc.swap(next);
  }

  // The last window is {end_db} when fixed; free: the argmin, ties to the smaller j.
  const Window last = windows[n - 1];
  int best_c = -1;
  int best_k = 0;
  double best_cost = kInf;
  for (int c = 0; c < last.width; ++c) {
    int k = 0;
    const double v = MinState(acc, c, states, &k);
    if (v < best_cost) {
      best_cost = v;
      best_c = c;
      best_k = k;
    }
  }
  if (best_c < 0) {
    result.failure = "no path within the search windows";
    return result;
  }

  result.db_index.resize(n);
  result.evidence.resize(n);
  int c = best_c;
  int k = best_k;
  for (int i = n - 1; i >= 0; --i) {
    const int j = windows[i].lo + c;
    result.db_index[i] = j;
    result.evidence[i] = costs.Get(i, j).has_value();
    if (i == 0) break;
    const int prev_k = back[back_offset[i] + static_cast<size_t>(c) * states + k];
    c = j - k - windows[i - 1].lo;
    k = prev_k;
  }
  result.total_cost = best_cost;
  result.valid = true;
  return result;
}

}  // namespace

void DtwOptions::Check() const {
  EPILOC_CHECK(max_step >= 1 && max_step <= kMaxStep, "dtw: max_step must be in [1, {}], got {}",
               kMaxStep, max_step);
  EPILOC_CHECK(GoodCost(missing_cost), "dtw: missing_cost must be finite and >= 0, got {}",
               missing_cost);
  EPILOC_CHECK(GoodCost(step_penalty), "dtw: step_penalty must be finite and >= 0, got {}",
               step_penalty);
  EPILOC_CHECK(band >= 0 && band <= kMaxBand, "dtw: band must be in [0, {}], got {}", kMaxBand,
               band);
}

SparseCostMatrix::SparseCostMatrix(int num_query, int num_db) : num_db_(num_db) {
  EPILOC_CHECK(num_query >= 0, "dtw: num_query must be >= 0, got {}", num_query);
  EPILOC_CHECK(num_db >= 1, "dtw: num_db must be >= 1, got {}", num_db);
  rows_.resize(num_query);
}

void SparseCostMatrix::Set(int i, int j, double cost) {
  EPILOC_CHECK(i >= 0 && i < num_query(), "dtw: query row {} outside [0, {})", i, num_query());
  EPILOC_CHECK(j >= 0 && j < num_db_, "dtw: DB frame {} outside [0, {})", j, num_db_);
  EPILOC_CHECK(GoodCost(cost), "dtw: cost of cell ({}, {}) must be finite and >= 0, got {}", i, j,
               cost);
  std::vector<Entry>& row = rows_[i];
  if (row.empty() || row.back().first < j) {
    row.emplace_back(j, cost);
    ++num_entries_;
    return;
  }
  auto it = std::lower_bound(row.begin(), row.end(), j,
                             [](const Entry& e, int key) { return e.first < key; });
  if (it != row.end() && it->first == j) {
    it->second = cost;
  } else {
    row.insert(it, Entry(j, cost));
    ++num_entries_;
  }
}

std::optional<double> SparseCostMatrix::Get(int i, int j) const {
  const std::vector<Entry>& row = Row(i);
  auto it = std::lower_bound(row.begin(), row.end(), j,
                             [](const Entry& e, int key) { return e.first < key; });
  if (it == row.end() || it->first != j) return std::nullopt;
  return it->second;
}

const std::vector<SparseCostMatrix::Entry>& SparseCostMatrix::Row(int i) const {
  EPILOC_CHECK(i >= 0 && i < num_query(), "dtw: query row {} outside [0, {})", i, num_query());
  return rows_[i];
}

DtwResult AlignFixed(const SparseCostMatrix& costs,
                     int start_db,
                     int end_db,
                     const DtwOptions& options) {
  return Align(costs, start_db, end_db, options);
}

DtwResult AlignFree(const SparseCostMatrix& costs, int start_db, const DtwOptions& options) {
  return Align(costs, start_db, std::nullopt, options);
}

OnlineDtw::OnlineDtw(int num_db, int start_db, const DtwOptions& options)
    : options_(options), num_db_(num_db), start_db_(start_db), current_(start_db) {
  options_.Check();
  EPILOC_CHECK(num_db >= 1, "dtw: num_db must be >= 1, got {}", num_db);
  Reset(start_db);
}

void OnlineDtw::Reset(int start_db) {
  EPILOC_CHECK(start_db >= 0 && start_db < num_db_, "dtw: start_db {} outside [0, {})", start_db,
               num_db_);
  start_db_ = start_db;
  current_ = start_db;
  evidence_ = false;
  num_rows_ = 0;
  window_lo_ = start_db;
  window_width_ = 0;
  acc_.clear();
}

int OnlineDtw::Push(const std::vector<std::pair<int, double>>& row_costs) {
  const int states = options_.max_step + 1;
  const Window prev{window_lo_, window_width_};
  const Window window =
      num_rows_ == 0
          ? Window{start_db_, 1}
          : Window{prev.lo, std::min(prev.hi() + options_.max_step, num_db_ - 1) - prev.lo + 1};
  row_cost_.assign(window.width, options_.missing_cost);
  for (const auto& [j, cost] : row_costs) {
    EPILOC_CHECK(j >= 0 && j < num_db_, "dtw: DB frame {} outside [0, {})", j, num_db_);
    EPILOC_CHECK(GoodCost(cost), "dtw: cost of DB frame {} must be finite and >= 0, got {}", j,
                 cost);
    if (j >= window.lo && j <= window.hi()) row_cost_[j - window.lo] = cost;
  }
  if (num_rows_ == 0) {
    next_.assign(states, row_cost_[0]);
  } else {
    Relax(acc_, prev.width, states, options_.step_penalty, &relaxed_, &relaxed_arg_);
    AdvanceRow(relaxed_, relaxed_arg_, prev, row_cost_, window, states, &next_, nullptr);
  }

  // Ties go to the smallest move from the previous best, forward before backward.
  auto closer = [this](int a, int b) {
    const int da = std::abs(a - current_), db = std::abs(b - current_);
    return da != db ? da < db : a > b;
  };
  int best_j = window.lo;
  double best_cost = kInf;
  for (int c = 0; c < window.width; ++c) {
    const double v = MinState(next_, c, states);
    const int j = window.lo + c;
    if (v < best_cost || (v == best_cost && closer(j, best_j))) {
      best_cost = v;
      best_j = j;
    }
  }

  const int lo = std::max(window.lo, best_j - options_.band);
  const int hi = std::min(window.hi(), best_j + options_.band);
  acc_.assign(next_.begin() + static_cast<size_t>(lo - window.lo) * states,
              next_.begin() + static_cast<size_t>(hi - window.lo + 1) * states);
  for (double& v : acc_) v -= best_cost;
  window_lo_ = lo;
  window_width_ = hi - lo + 1;

  current_ = best_j;
  evidence_ = std::any_of(row_costs.begin(), row_costs.end(),
                          [best_j](const std::pair<int, double>& e) { return e.first == best_j; });
  ++num_rows_;
  return current_;
}

}  // namespace epiloc
