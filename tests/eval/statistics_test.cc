#include "epiloc/eval/statistics.h"

#include <cmath>

#include <gtest/gtest.h>

#include "eval_test_util.h"

namespace epiloc {
namespace {

TEST(Percentile, InterpolatesLinearlyBetweenOrderStatistics) {
  // numpy.percentile([1, 2, 3, 4], q): h = q/100 * 3.
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 0), 1.0);
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 100), 4.0);
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 50), 2.5);   // h = 1.5
  EXPECT_DOUBLE_EQ(Percentile({4, 1, 3, 2}, 95), 3.85);  // h = 2.85: 3 + 0.85 * (4 - 3)
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 25), 1.75);  // h = 0.75
  // [10, 20, 30, 40, 50]: h = 0.95 * 4 = 3.8 -> 40 + 0.8 * 10.
  EXPECT_DOUBLE_EQ(Percentile({50, 10, 40, 20, 30}, 95), 48.0);
  EXPECT_DOUBLE_EQ(Percentile({10, 20, 30, 40, 50}, 25), 20.0);  // h = 1 exactly
  EXPECT_DOUBLE_EQ(Percentile({7.5}, 95), 7.5);
  ExpectError([] { Percentile({}, 50); }, {"no values"});
  ExpectError([] { Percentile({1, 2}, 101); }, {"101"});
}

TEST(ErrorStatistics, MatchesHandComputedValues) {
  // e = -0.3, 0.1, 0.2, 1.5, -2.0; |e| sorted = 0.1, 0.2, 0.3, 1.5, 2.0.
  const ErrorStatistics s = ComputeErrorStatistics({-0.3, 0.1, 0.2, 1.5, -2.0});
  EXPECT_EQ(s.count, 5);
  EXPECT_DOUBLE_EQ(s.min, -2.0);
  EXPECT_DOUBLE_EQ(s.max, 1.5);
  EXPECT_NEAR(s.mean_abs, 0.82, 1e-12);      // 4.1 / 5
  EXPECT_NEAR(s.bias, -0.1, 1e-12);          // -0.5 / 5
  EXPECT_NEAR(s.rmse, 1.1304866209, 1e-9);   // sqrt(6.39 / 5) = sqrt(1.278)
  EXPECT_NEAR(s.std, 1.1260550608, 1e-9);    // sqrt(1.278 - 0.01) = sqrt(1.268)
  EXPECT_NEAR(s.median_abs, 0.3, 1e-12);     // middle of five
  EXPECT_NEAR(s.p95_abs, 1.9, 1e-12);        // h = 3.8: 1.5 + 0.8 * 0.5
  ASSERT_EQ(s.share_within.size(), 5u);      // <= 0.1, 0.25, 0.5, 1, 2 m
  EXPECT_DOUBLE_EQ(s.share_within[0], 0.2);  // 0.1
  EXPECT_DOUBLE_EQ(s.share_within[1], 0.4);  // 0.1, 0.2
  EXPECT_DOUBLE_EQ(s.share_within[2], 0.6);  // + 0.3
  EXPECT_DOUBLE_EQ(s.share_within[3], 0.6);
  EXPECT_DOUBLE_EQ(s.share_within[4], 1.0);  // 2.0 <= 2 counts
}

TEST(ErrorStatistics, ConstantErrorHasNoSpread) {
  const ErrorStatistics s = ComputeErrorStatistics({0.5, 0.5, 0.5, 0.5});
  EXPECT_DOUBLE_EQ(s.bias, 0.5);
  EXPECT_DOUBLE_EQ(s.std, 0.0);
  EXPECT_DOUBLE_EQ(s.rmse, 0.5);
  EXPECT_DOUBLE_EQ(s.share_within[1], 0.0);
  EXPECT_DOUBLE_EQ(s.share_within[2], 1.0);
}

TEST(ErrorStatistics, EmptyGivesNaN) {
  const ErrorStatistics s = ComputeErrorStatistics({});
  EXPECT_EQ(s.count, 0);
  EXPECT_TRUE(std::isnan(s.rmse));
  EXPECT_TRUE(std::isnan(s.min));
  ASSERT_EQ(s.share_within.size(), ErrorThresholds().size());
  EXPECT_TRUE(std::isnan(s.share_within[0]));
}

}  // namespace
}  // namespace epiloc
