#include "epiloc/localize/track_filter.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

TEST(TrackFilter, FollowsAConstantSpeed) {
  AlongTrackFilter filter;
  EXPECT_FALSE(filter.initialised());
  filter.Initialise(0.0, 10.0, 0.05);
  EXPECT_NEAR(filter.sigma_v_mps(), 15.0, 1e-9);
  for (int i = 1; i <= 30; ++i) {
    const double t = 0.1 * i;
    filter.Predict(t);
    const double s = 10.0 + 8.0 * t;
    ASSERT_TRUE(filter.Accepts(s, 0.05)) << i;
    filter.Update(s, 0.05);
  }
  EXPECT_NEAR(filter.s_m(), 34.0, 1e-3);
  EXPECT_NEAR(filter.v_mps(), 8.0, 0.05);
  EXPECT_LT(filter.sigma_s_m(), 0.05);
  // The prediction carries the speed on.
  filter.Predict(3.5);
  EXPECT_NEAR(filter.s_m(), 38.0, 0.05);
  filter.Predict(3.4);  // back in time: no change
  EXPECT_NEAR(filter.timestamp_s(), 3.5, 1e-12);
}

// A jump the vehicle cannot make between two frames is refused; the same jump after a long gap
// in the input is possible and accepted.
TEST(TrackFilter, RefusesImpossibleJumpsAndAcceptsThemAfterAGap) {
  AlongTrackFilter filter;
  filter.Initialise(0.0, 10.0, 0.05);
  for (int i = 1; i <= 20; ++i) {
    filter.Predict(0.1 * i);
    filter.Update(10.0 + 0.5 * i, 0.05);  // 5 m/s
  }
  filter.Predict(2.1);
  EXPECT_NEAR(filter.s_m(), 20.5, 0.05);
  EXPECT_FALSE(filter.Accepts(20.5 + 6.0, 0.1)) << "6 m ahead in 0.1 s (60 m/s more)";
  EXPECT_FALSE(filter.Accepts(20.5 + 1.0, 0.1));
  EXPECT_TRUE(filter.Accepts(20.5 + 0.1, 0.1));
  filter.Predict(12.1);  // ten seconds without input
  EXPECT_TRUE(filter.Accepts(20.5 + 50.0 + 30.0, 0.1));
}

// A creeping vehicle: measurements 2 cm apart per frame give a slow speed, and a precise
// prediction that keeps the next frame within centimetres.
TEST(TrackFilter, CreepingKeepsASlowSpeed) {
  AlongTrackFilter filter;
  filter.Initialise(0.0, 5.0, 0.05);
  for (int i = 1; i <= 50; ++i) {
    filter.Predict(0.1 * i);
    filter.Update(5.0 + 0.02 * i, 0.05);
  }
  EXPECT_NEAR(filter.v_mps(), 0.2, 0.05);
  EXPECT_FALSE(filter.Accepts(filter.s_m() + 1.0, 0.05));
}

TEST(TrackFilter, SpeedStaysWithinTheLimits) {
  TrackFilterOptions options;
  options.gate_chi2 = 1e12;  // no gating: only the limits act
  AlongTrackFilter filter(options);
  filter.Initialise(0.0, 0.0, 0.01);
  for (int i = 1; i <= 10; ++i) {
    filter.Predict(0.1 * i);
    filter.Update(20.0 * i, 0.01);  // 200 m/s
  }
  EXPECT_LE(filter.v_mps(), options.max_speed_mps + 1e-9);
  filter.Initialise(0.0, 100.0, 0.01);
  for (int i = 1; i <= 10; ++i) {
    filter.Predict(0.1 * i);
    filter.Update(100.0 - 2.0 * i, 0.01);  // 20 m/s backwards
  }
  EXPECT_GE(filter.v_mps(), -options.max_reverse_mps - 1e-9);
}

TEST(TrackFilter, OptionsAreChecked) {
  TrackFilterOptions options;
  options.accel_sigma_mps2 = 0.0;
  EXPECT_THROW(AlongTrackFilter{options}, Error);
  options = TrackFilterOptions();
  options.gate_chi2 = -1.0;
  EXPECT_THROW(AlongTrackFilter{options}, Error);
}

}  // namespace
}  // namespace epiloc
