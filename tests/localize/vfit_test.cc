#include "epiloc/localize/vfit.h"

#include <cmath>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using ::testing::HasSubstr;

constexpr double kSlope = 1.8;
constexpr double kSpacing_m = 0.9;

// Database frames at s = 0, 0.9, ..., 7.2 m; d = a |s - l| exactly, signed by the side of l.
std::vector<VFitPoint> ExactV(double l_m, int count = 9, double first_m = 0.0) {
  std::vector<VFitPoint> points;
  for (int k = 0; k < count; ++k) {
    const double s = first_m + k * kSpacing_m;
    points.push_back({s, kSlope * std::abs(s - l_m), s > l_m ? 1 : (s < l_m ? -1 : 0)});
  }
  return points;
}

// Multiplies every d by (1 + relative * N(0, 1)).
void AddNoise(std::vector<VFitPoint>* points, double relative, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, relative);
  for (VFitPoint& p : *points) p.d = std::max(0.0, p.d * (1.0 + noise(rng)));
}

VFitOptions Mode(bool use_sign) {
  VFitOptions options;
  options.use_sign = use_sign;
  return options;
}

class VFitModes : public ::testing::TestWithParam<bool> {};  // use_sign

TEST_P(VFitModes, ExactVGivesExactPosition) {
  // Between two samples, at a sample, near either end, and just beyond the last sample.
  for (double l : {3.37, 2.7, 0.1, 7.0, 7.2, 7.6}) {
    const VFitResult r = FitV(ExactV(l), Mode(GetParam()));
    ASSERT_TRUE(r.valid) << "l = " << l << ": " << r.failure;
    EXPECT_NEAR(r.l_m, l, 1e-9);
    EXPECT_NEAR(r.slope, kSlope, 1e-9);
    EXPECT_NEAR(r.rms_residual, 0.0, 1e-9);
    EXPECT_EQ(r.num_inliers, 9);
    EXPECT_THAT(r.inliers, ::testing::Each(true));
  }
}

TEST_P(VFitModes, FivePercentNoise) {
  double sum_error = 0.0;
  constexpr int kSeeds = 20;
  for (int seed = 0; seed < kSeeds; ++seed) {
    std::mt19937_64 rng(seed);
    std::vector<VFitPoint> points = ExactV(3.37);
    AddNoise(&points, 0.05, rng);
    const VFitResult r = FitV(points, Mode(GetParam()));
    ASSERT_TRUE(r.valid) << "seed " << seed << ": " << r.failure;
    EXPECT_NEAR(r.l_m, 3.37, 0.15) << "seed " << seed;
    EXPECT_NEAR(r.rms_residual_m, r.rms_residual / r.slope, 1e-12);
    EXPECT_GT(r.rms_residual, 0.0);
    sum_error += std::abs(r.l_m - 3.37);
  }
  EXPECT_LT(sum_error / kSeeds, 0.05);
}

TEST_P(VFitModes, GrossOutliersAreFlagged) {
  for (int seed = 0; seed < 10; ++seed) {
    std::mt19937_64 rng(100 + seed);
    std::vector<VFitPoint> points = ExactV(3.37);
    AddNoise(&points, 0.05, rng);
    points[1].d = 0.3;  // a wrong match close to zero far from l
    points[6].d += 5.0;
    const VFitResult r = FitV(points, Mode(GetParam()));
    ASSERT_TRUE(r.valid) << "seed " << seed << ": " << r.failure;
    EXPECT_NEAR(r.l_m, 3.37, 0.1) << "seed " << seed;
    EXPECT_FALSE(r.inliers[1]);
    EXPECT_FALSE(r.inliers[6]);
    EXPECT_EQ(r.num_inliers, 7) << "seed " << seed;
  }
}

TEST_P(VFitModes, FarExtrapolationIsInvalid) {
  // All samples ahead of l by more than one spacing: the line's root is a guess.
  const VFitResult r = FitV(ExactV(-3.0), Mode(GetParam()));
  EXPECT_FALSE(r.valid);
  EXPECT_THAT(r.failure, HasSubstr("extrapolation"));
  EXPECT_NEAR(r.l_m, -3.0, 1e-9);
  // Within one spacing behind the first sample is accepted.
  const VFitResult near = FitV(ExactV(-0.8), Mode(GetParam()));
  EXPECT_TRUE(near.valid) << near.failure;
  EXPECT_NEAR(near.l_m, -0.8, 1e-9);
}

TEST_P(VFitModes, TooFewPointsOrInliers) {
  const std::vector<VFitPoint> all = ExactV(3.37);
  const VFitResult two = FitV({all[0], all[8]}, Mode(GetParam()));
  EXPECT_FALSE(two.valid);
  EXPECT_THAT(two.failure, HasSubstr("too few points"));
  EXPECT_EQ(two.inliers.size(), 2u);
  std::vector<VFitPoint> three = {all[0], all[1], all[2]};
  three[2].d = 20.0;
  const VFitResult r = FitV(three, Mode(GetParam()));
  EXPECT_FALSE(r.valid);
  EXPECT_THAT(r.failure, HasSubstr("too few inliers"));
}

TEST_P(VFitModes, AllPointsAtOneSIsDegenerate) {
  const std::vector<VFitPoint> points(4, VFitPoint{2.0, 1.0, 1});
  const VFitResult r = FitV(points, Mode(GetParam()));
  EXPECT_FALSE(r.valid);
  EXPECT_THAT(r.failure, HasSubstr("one s"));
}

INSTANTIATE_TEST_SUITE_P(Modes,
                         VFitModes,
                         ::testing::Values(true, false),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? "signed" : "unsigned";
                         });

TEST(VFit, WrongSignIsAnOutlierOnlyWhenSignsAreUsed) {
  std::vector<VFitPoint> points = ExactV(3.37);
  points[0].sign = 1;  // claims to be ahead though it is 3.37 m behind
  const VFitResult with_sign = FitV(points, Mode(true));
  ASSERT_TRUE(with_sign.valid) << with_sign.failure;
  EXPECT_NEAR(with_sign.l_m, 3.37, 1e-9);
  EXPECT_FALSE(with_sign.inliers[0]);
  EXPECT_EQ(with_sign.num_inliers, 8);
  const VFitResult without = FitV(points, Mode(false));
  ASSERT_TRUE(without.valid) << without.failure;
  EXPECT_NEAR(without.l_m, 3.37, 1e-9);
  EXPECT_EQ(without.num_inliers, 9);
}

TEST(VFit, AllSignsFlippedGivesNoPositiveSlope) {
  std::vector<VFitPoint> points = ExactV(3.37);
  for (VFitPoint& p : points) p.sign = -p.sign;
  const VFitResult r = FitV(points, Mode(true));
  EXPECT_FALSE(r.valid);
  EXPECT_THAT(r.failure, HasSubstr("slope"));
}

TEST(VFit, UnknownSignsMixWithKnownOnes) {
  std::vector<VFitPoint> points = ExactV(5.05);
  for (size_t k = 0; k < points.size(); k += 2) points[k].sign = 0;
  const VFitResult r = FitV(points, Mode(true));
  ASSERT_TRUE(r.valid) << r.failure;
  EXPECT_NEAR(r.l_m, 5.05, 1e-9);
  EXPECT_NEAR(r.slope, kSlope, 1e-9);
}

TEST(VFit, SampledRansacIsDeterministicPerSeed) {
  // 40 points: more pairs than ransac_iterations, so pairs are drawn at random.
  std::mt19937_64 rng(42);
  std::vector<VFitPoint> points = ExactV(12.34, 40);
  AddNoise(&points, 0.05, rng);
  std::uniform_real_distribution<double> junk(0.0, 60.0);
  for (int k = 0; k < 40; k += 5) points[k].d = junk(rng);  // 8 outliers
  for (bool use_sign : {true, false}) {
    VFitOptions options = Mode(use_sign);
    options.seed = 7;
    const VFitResult a = FitV(points, options);
    const VFitResult b = FitV(points, options);
    ASSERT_TRUE(a.valid) << a.failure;
    EXPECT_EQ(a.l_m, b.l_m);
    EXPECT_EQ(a.inliers, b.inliers);
    EXPECT_NEAR(a.l_m, 12.34, 0.1);
    EXPECT_GE(a.num_inliers, 30);
  }
}

TEST(VFit, BadInputThrows) {
  std::vector<VFitPoint> points = ExactV(3.37);
  points[2].d = -1.0;
  EXPECT_THROW(FitV(points, VFitOptions()), Error);
  points = ExactV(3.37);
  points[2].sign = 2;
  EXPECT_THROW(FitV(points, VFitOptions()), Error);
  points = ExactV(3.37);
  points[2].s_m = std::nan("");
  EXPECT_THROW(FitV(points, VFitOptions()), Error);
  VFitOptions options;
  options.min_points = 1;
  EXPECT_THROW(FitV(ExactV(3.37), options), Error);
  options = VFitOptions();
  options.max_residual_fraction = 0.0;
  EXPECT_THROW(options.Check(), Error);
}

}  // namespace
}  // namespace epiloc
