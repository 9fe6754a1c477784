#include "epiloc/core/statistics.h"

#include <gtest/gtest.h>

namespace epiloc {
namespace {

TEST(Statistics, MedianOfOddAndEvenCounts) {
  EXPECT_EQ(Median({}), 0.0);
  EXPECT_EQ(Median({4.0}), 4.0);
  EXPECT_EQ(Median({5.0, -1.0, 3.0}), 3.0);
  EXPECT_EQ(Median({7.0, 1.0, 3.0, 100.0}), 5.0);  // the mean of 3 and 7
  EXPECT_EQ(Median({2.0, 2.0, 2.0, 9.0}), 2.0);
}

TEST(Statistics, UpperMedianIsOneOfTheValues) {
  EXPECT_EQ(UpperMedian({}), 0.0);
  EXPECT_EQ(UpperMedian({4.0}), 4.0);
  EXPECT_EQ(UpperMedian({5.0, -1.0, 3.0}), 3.0);
  EXPECT_EQ(UpperMedian({7.0, 1.0, 3.0, 100.0}), 7.0);  // the larger middle one
  EXPECT_EQ(UpperMedian({1.0, 2.0}), 2.0);
}

}  // namespace
}  // namespace epiloc
