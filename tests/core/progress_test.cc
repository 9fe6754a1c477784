#include "epiloc/core/progress.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace epiloc {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

TEST(FormatDuration, SecondsMinutesHours) {
  EXPECT_EQ(FormatDuration(0.0), "0s");
  EXPECT_EQ(FormatDuration(12.4), "12s");
  EXPECT_EQ(FormatDuration(59.4), "59s");
  EXPECT_EQ(FormatDuration(59.6), "1m00s");
  EXPECT_EQ(FormatDuration(185.0), "3m05s");
  EXPECT_EQ(FormatDuration(3599.0), "59m59s");
  EXPECT_EQ(FormatDuration(3600.0), "1h00m");
  EXPECT_EQ(FormatDuration(3725.0), "1h02m");
  EXPECT_EQ(FormatDuration(100.0 * 3600.0), "100h00m");
}

TEST(FormatDuration, UnknownForInvalidValues) {
  EXPECT_EQ(FormatDuration(-1.0), "?");
  EXPECT_EQ(FormatDuration(std::nan("")), "?");
  EXPECT_EQ(FormatDuration(std::numeric_limits<double>::infinity()), "?");
}

TEST(Progress, LineShowsBarCountPercentRateAndEta) {
  Progress progress("build-db", 10, ProgressStyle::kQuiet);
  progress.Add(5);
  const std::string line = progress.Line();
  EXPECT_THAT(line, StartsWith("build-db ["));
  // Half of the 24-character bar.
  EXPECT_THAT(line, HasSubstr("[============>           ]"));
  EXPECT_THAT(line, HasSubstr(" 5/10 "));
  EXPECT_THAT(line, HasSubstr(" 50%"));
  EXPECT_THAT(line, HasSubstr("/s ETA "));
  EXPECT_THAT(line, HasSubstr(" elapsed "));
  EXPECT_THAT(
      line,
      Not(HasSubstr("ETA ?")));  // some time has passed, so the rate is known
}

TEST(Progress, LineAtStartAndEnd) {
  Progress progress("extract", 4, ProgressStyle::kQuiet);
  EXPECT_THAT(progress.Line(),
              HasSubstr("[>                       ] 0/4   0%"));
  progress.Add();
  progress.Add(3);
  EXPECT_THAT(progress.Line(),
              HasSubstr("[========================] 4/4 100%"));
  EXPECT_THAT(progress.Line(), HasSubstr("ETA 0s"));
  progress.Set(2);
  EXPECT_THAT(progress.Line(), HasSubstr(" 2/4  50%"));
  // More than the total is shown as it is, the bar stays full.
  progress.Set(6);
  EXPECT_THAT(progress.Line(),
              HasSubstr("[========================] 6/4 100%"));
  progress.Finish();
  progress.Finish();  // a second call does nothing
}

TEST(Progress, UnknownTotalShowsCountAndRate) {
  Progress progress("frames", 0, ProgressStyle::kQuiet);
  progress.Add(3);
  const std::string line = progress.Line();
  EXPECT_THAT(line, StartsWith("frames 3 "));
  EXPECT_THAT(line, HasSubstr("/s elapsed "));
  EXPECT_THAT(line, Not(HasSubstr("[")));
  EXPECT_THAT(line, Not(HasSubstr("ETA")));
}

TEST(Progress, CallbackSetsCountAndTotal) {
  Progress progress("cb", 100, ProgressStyle::kQuiet);
  const ProgressCallback callback = progress.Callback();
  callback(25, 100);
  EXPECT_THAT(progress.Line(), HasSubstr(" 25/100  25%"));
  callback(50, 200);
  EXPECT_THAT(progress.Line(), HasSubstr(" 50/200  25%"));
}

TEST(Progress, TotalCanBeSetLater) {
  Progress progress("later", 0, ProgressStyle::kQuiet);
  progress.Add(2);
  EXPECT_THAT(progress.Line(), Not(HasSubstr("%")));
  progress.SetTotal(8);
  EXPECT_THAT(progress.Line(), HasSubstr(" 2/8  25%"));
  progress.SetTotal(-5);  // clamped to unknown
  EXPECT_THAT(progress.Line(), StartsWith("later 2 "));
}

TEST(Progress, DefaultStyleIsSettable) {
  const ProgressStyle before = DefaultProgressStyle();
  SetDefaultProgressStyle(ProgressStyle::kQuiet);
  EXPECT_EQ(DefaultProgressStyle(), ProgressStyle::kQuiet);
  SetDefaultProgressStyle(before);
  EXPECT_EQ(DefaultProgressStyle(), before);
}

}  // namespace
}  // namespace epiloc
