#include "epiloc/localize/dtw.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <set>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using Row = std::vector<std::pair<int, double>>;

// Along-route positions (metres) of a query drive of n frames; DB frame j lies at s = j metres.
// Every position is 0.2 or 0.7 past a whole metre, so the nearest DB frame is never a tie.
std::vector<double> Track(const std::string& profile, int n, double start_m = 5.2) {
  std::vector<double> s(n, start_m);
  for (int i = 1; i < n; ++i) {
    double v = 1.0;  // "same_speed": one DB frame per query frame
    if (profile == "twice_as_fast") v = 2.0;
    if (profile == "half_as_fast") v = 0.5;
    if (profile == "stop") v = i >= n / 3 && i < n / 2 ? 0.0 : 1.0;
    if (profile == "speed_change") v = i < n / 3 ? 1.0 : i < 2 * n / 3 ? 2.5 : 0.5;
    s[i] = s[i - 1] + v;
  }
  return s;
}

std::vector<int> Truth(const std::vector<double>& s) {
  std::vector<int> j;
  for (double x : s) j.push_back(static_cast<int>(std::lround(x)));
  return j;
}

// Per row 20 evaluated cells around a prior that is off the truth by up to 3 frames, cost
// min(1, |s_i - s_j| / 10 m) plus uniform noise in [0, noise). Rows in `missing` are empty; rows
// in `spurious` also get a false cost-0 cell 8 frames ahead of the truth.
std::vector<Row> MakeRows(const std::vector<double>& s,
                          int num_db,
                          const std::set<int>& missing,
                          const std::set<int>& spurious,
                          double noise,
                          std::mt19937_64& rng) {
  std::uniform_real_distribution<double> jitter(0.0, 1.0);
  std::uniform_int_distribution<int> prior_offset(-3, 3);
  std::vector<Row> rows(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    if (missing.count(static_cast<int>(i))) continue;
    const int truth = static_cast<int>(std::lround(s[i]));
    const int prior = truth + prior_offset(rng);
    for (int j = std::max(0, prior - 10); j < std::min(num_db, prior + 10); ++j) {
      rows[i].emplace_back(j, std::min(1.0, std::abs(s[i] - j) / 10.0) + noise * jitter(rng));
    }
    if (spurious.count(static_cast<int>(i)) && truth + 8 < num_db) {
      rows[i].erase(std::remove_if(rows[i].begin(), rows[i].end(),
                                   [&](const auto& e) { return e.first == truth + 8; }),
                    rows[i].end());
      rows[i].emplace_back(truth + 8, 0.0);
    }
  }
  return rows;
}

SparseCostMatrix ToMatrix(const std::vector<Row>& rows, int num_db) {
  SparseCostMatrix matrix(static_cast<int>(rows.size()), num_db);
  for (size_t i = 0; i < rows.size(); ++i) {
    for (const auto& [j, cost] : rows[i]) matrix.Set(static_cast<int>(i), j, cost);
  }
  return matrix;
}

// The share of rows from `warm_up` on where the estimate equals the truth.
double OnlineHitRate(OnlineDtw& dtw,
                     const std::vector<Row>& rows,
                     const std::vector<int>& truth,
                     int warm_up) {
  int hits = 0;
  for (size_t i = 0; i < rows.size(); ++i) {
    const int j = dtw.Push(rows[i]);
    if (static_cast<int>(i) >= warm_up && j == truth[i]) ++hits;
  }
  return static_cast<double>(hits) / (rows.size() - warm_up);
}

TEST(SparseCostMatrix, StoresRowsSortedAndOverwrites) {
  SparseCostMatrix m(3, 10);
  m.Set(1, 7, 0.5);
  m.Set(1, 2, 0.25);
  m.Set(1, 4, 0.0);
  m.Set(1, 7, 0.75);
  EXPECT_EQ(m.num_entries(), 3);
  EXPECT_EQ(m.Row(1), (Row{{2, 0.25}, {4, 0.0}, {7, 0.75}}));
  EXPECT_EQ(m.Get(1, 7), 0.75);
  EXPECT_FALSE(m.Get(1, 3).has_value());
  EXPECT_FALSE(m.Get(0, 7).has_value());
  EXPECT_THROW(m.Set(3, 0, 0.1), Error);
  EXPECT_THROW(m.Set(0, 10, 0.1), Error);
  EXPECT_THROW(m.Set(0, 1, -0.1), Error);
  EXPECT_THROW(m.Set(0, 1, std::nan("")), Error);
  EXPECT_THROW(SparseCostMatrix(1, 0), Error);
}

TEST(DtwOptions, CheckRejectsBadValues) {
  DtwOptions ok;
  EXPECT_NO_THROW(ok.Check());
  DtwOptions o = ok;
  o.max_step = 0;
  EXPECT_THROW(o.Check(), Error);
  o = ok;
  o.missing_cost = -1;
  EXPECT_THROW(o.Check(), Error);
  o = ok;
  o.step_penalty = std::nan("");
  EXPECT_THROW(o.Check(), Error);
  o = ok;
  o.band = -1;
  EXPECT_THROW(o.Check(), Error);
}

class DtwProfile : public ::testing::TestWithParam<std::string> {
 protected:
  static constexpr int kRows = 200;
  void SetUp() override {
    s_ = Track(GetParam(), kRows);
    truth_ = Truth(s_);
    num_db_ = truth_.back() + 40;
  }
  std::vector<double> s_;
  std::vector<int> truth_;
  int num_db_ = 0;
  const std::set<int> missing_{20, 21, 22, 90, 150};
  const std::set<int> spurious_{30, 100, 160};
};

TEST_P(DtwProfile, FixedRecoversExactPath) {
  std::mt19937_64 rng(1);
  const SparseCostMatrix costs = ToMatrix(MakeRows(s_, num_db_, missing_, {}, 0.0, rng), num_db_);
  const DtwResult r = AlignFixed(costs, truth_.front(), truth_.back(), DtwOptions());
  ASSERT_TRUE(r.valid) << r.failure;
  ASSERT_EQ(r.db_index.size(), truth_.size());
  double expected_cost = 0.0;
  for (int i = 0; i < kRows; ++i) {
    EXPECT_EQ(r.evidence[i], !missing_.count(i)) << "row " << i;
    if (missing_.count(i)) {
      expected_cost += 1.0;
      continue;
    }
    EXPECT_EQ(r.db_index[i], truth_[i]) << "row " << i;
    expected_cost += std::abs(s_[i] - truth_[i]) / 10.0;
  }
  EXPECT_NEAR(r.total_cost, expected_cost, 1e-9);
  for (int i = 1; i < kRows; ++i) {
    const int step = r.db_index[i] - r.db_index[i - 1];
    EXPECT_GE(step, 0);
    EXPECT_LE(step, DtwOptions().max_step);
  }
}

TEST_P(DtwProfile, FixedAndFreeIgnoreNoiseAndSpuriousMinima) {
  std::mt19937_64 rng(2);
  const SparseCostMatrix costs =
      ToMatrix(MakeRows(s_, num_db_, missing_, spurious_, 0.015, rng), num_db_);
  const DtwResult fixed = AlignFixed(costs, truth_.front(), truth_.back(), DtwOptions());
  const DtwResult free = AlignFree(costs, truth_.front(), DtwOptions());
  ASSERT_TRUE(fixed.valid) << fixed.failure;
  ASSERT_TRUE(free.valid) << free.failure;
  for (int i = 0; i < kRows; ++i) {
    if (missing_.count(i)) continue;
    EXPECT_EQ(fixed.db_index[i], truth_[i]) << "row " << i;
    EXPECT_EQ(free.db_index[i], truth_[i]) << "row " << i;
  }
  EXPECT_EQ(free.db_index.back(), truth_.back());
}

TEST_P(DtwProfile, OnlineMatchesTruthAfterWarmUp) {
  std::mt19937_64 rng(3);
  const std::vector<Row> rows = MakeRows(s_, num_db_, {20, 90, 150}, spurious_, 0.015, rng);
  OnlineDtw dtw(num_db_, truth_.front(), DtwOptions());
  EXPECT_GE(OnlineHitRate(dtw, rows, truth_, 5), 0.95);
  EXPECT_EQ(dtw.num_rows(), kRows);
  EXPECT_TRUE(dtw.evidence());
}

INSTANTIATE_TEST_SUITE_P(
    Speeds,
    DtwProfile,
    ::testing::Values("same_speed", "twice_as_fast", "half_as_fast", "stop", "speed_change"),
    [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

TEST(Dtw, StepPenaltyInterpolatesRowsWithoutEvidence) {
  std::mt19937_64 rng(4);
  const std::vector<double> s = Track("same_speed", 100);
  const std::vector<int> truth = Truth(s);
  std::set<int> missing;
  for (int i = 40; i < 50; ++i) missing.insert(i);
  const SparseCostMatrix costs = ToMatrix(MakeRows(s, 200, missing, {}, 0.0, rng), 200);
  DtwOptions options;
  options.step_penalty = 0.01;
  const DtwResult r = AlignFree(costs, truth.front(), options);
  ASSERT_TRUE(r.valid) << r.failure;
  EXPECT_EQ(r.db_index, truth);
  EXPECT_FALSE(r.evidence[45]);
  EXPECT_TRUE(r.evidence[55]);

  // Online, the penalty carries the speed across the gap as well.
  OnlineDtw online(200, truth.front(), options);
  EXPECT_DOUBLE_EQ(OnlineHitRate(online, MakeRows(s, 200, missing, {}, 0.0, rng), truth, 1), 1.0);
}

TEST(Dtw, FixedRejectsUnreachableEnds) {
  SparseCostMatrix costs(5, 100);
  const DtwResult before = AlignFixed(costs, 10, 9, DtwOptions());
  EXPECT_FALSE(before.valid);
  EXPECT_THAT(before.failure, ::testing::HasSubstr("before start_db"));
  const DtwResult far = AlignFixed(costs, 10, 10 + 4 * 4 + 1, DtwOptions());
  EXPECT_FALSE(far.valid);
  EXPECT_THAT(far.failure, ::testing::HasSubstr("not reachable"));
  const DtwResult longest = AlignFixed(costs, 10, 10 + 4 * 4, DtwOptions());
  ASSERT_TRUE(longest.valid) << longest.failure;
  EXPECT_EQ(longest.db_index, (std::vector<int>{10, 14, 18, 22, 26}));
  EXPECT_DOUBLE_EQ(longest.total_cost, 5.0);
  EXPECT_FALSE(AlignFree(SparseCostMatrix(0, 10), 0, DtwOptions()).valid);
  EXPECT_THROW(AlignFixed(costs, 10, 100, DtwOptions()), Error);
  EXPECT_THROW(AlignFree(costs, -1, DtwOptions()), Error);
}

TEST(Dtw, LargeSparseProblemStaysInItsWindows) {
  std::mt19937_64 rng(5);
  constexpr int kQuery = 5000, kDb = 20000;
  std::vector<double> s(kQuery);
  for (int i = 0; i < kQuery; ++i) s[i] = 20.2 + 3.5 * i;  // steps of 3 and 4 DB frames
  const std::vector<int> truth = Truth(s);
  ASSERT_LT(truth.back(), kDb);
  const SparseCostMatrix costs = ToMatrix(MakeRows(s, kDb, {}, {}, 0.015, rng), kDb);
  ASSERT_EQ(costs.num_entries(), int64_t{20} * kQuery);
  const DtwOptions options;
  const DtwResult r = AlignFree(costs, truth.front(), options);
  ASSERT_TRUE(r.valid) << r.failure;
  EXPECT_EQ(r.db_index, truth);
  // Each row's window is its 20 cells +- band: nowhere near the dense N x M = 1e8.
  EXPECT_LE(r.num_cells, int64_t{kQuery} * (20 + 2 * options.band));
}

TEST(OnlineDtw, WorkDoesNotDependOnRouteLength) {
  std::mt19937_64 rng(6);
  constexpr int kDb = 100000, kRows = 10000;
  const std::vector<double> s = Track("same_speed", kRows, 50000.2);
  const std::vector<int> truth = Truth(s);
  const std::vector<Row> rows = MakeRows(s, kDb, {}, {}, 0.015, rng);
  OnlineDtw dtw(kDb, truth.front(), DtwOptions());
  const auto start = std::chrono::steady_clock::now();
  const double hit_rate = OnlineHitRate(dtw, rows, truth, 5);
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(elapsed_s, 1.0);
  EXPECT_GE(hit_rate, 0.95);
}

TEST(OnlineDtw, RowWithoutEvidenceKeepsTheEstimate) {
  OnlineDtw dtw(100, 10, DtwOptions());
  EXPECT_EQ(dtw.Push({{10, 0.0}, {11, 0.4}}), 10);
  EXPECT_TRUE(dtw.evidence());
  // Every reachable frame costs missing_cost: the smallest move (none) wins the tie.
  EXPECT_EQ(dtw.Push({}), 10);
  EXPECT_FALSE(dtw.evidence());
  EXPECT_EQ(dtw.Push({{11, 0.5}, {12, 0.0}}), 12);
  EXPECT_EQ(dtw.Push({{90, 0.0}}), 12);  // out of reach: ignored, the estimate stays
  EXPECT_FALSE(dtw.evidence());
}

TEST(OnlineDtw, ResetReanchors) {
  std::mt19937_64 rng(7);
  const int num_db = 600;
  const std::vector<double> a = Track("same_speed", 60, 20.2);
  const std::vector<double> b = Track("twice_as_fast", 60, 400.2);
  OnlineDtw dtw(num_db, Truth(a).front(), DtwOptions());
  EXPECT_EQ(dtw.current(), 20);
  EXPECT_FALSE(dtw.evidence());
  EXPECT_GE(OnlineHitRate(dtw, MakeRows(a, num_db, {}, {}, 0.015, rng), Truth(a), 5), 0.95);
  // The drive jumps to a place the band cannot reach: without Reset the estimate is lost.
  const std::vector<Row> rows_b = MakeRows(b, num_db, {}, {}, 0.015, rng);
  EXPECT_NE(dtw.Push(rows_b[0]), 400);
  dtw.Reset(400);
  EXPECT_EQ(dtw.num_rows(), 0);
  EXPECT_EQ(dtw.Push(rows_b[0]), 400);
  EXPECT_TRUE(dtw.evidence());
  EXPECT_EQ(dtw.num_rows(), 1);
  const std::vector<Row> rest(rows_b.begin() + 1, rows_b.end());
  const std::vector<int> truth_b = Truth(b);
  const std::vector<int> truth_rest(truth_b.begin() + 1, truth_b.end());
  EXPECT_GE(OnlineHitRate(dtw, rest, truth_rest, 4), 0.95);
  EXPECT_THROW(dtw.Reset(num_db), Error);
  EXPECT_THROW(dtw.Push({{num_db, 0.5}}), Error);
  EXPECT_THROW(dtw.Push({{3, -0.5}}), Error);
}

}  // namespace
}  // namespace epiloc
