// The along-track measurement from epipolar pairs on exact synthetic geometry: the signed
// cotangent u (PairResult::signed_cot) of each database camera at s_j seen from the query at l
// with a lateral offset Δy is (s_j - l) / Δy.
#include "epiloc/localize/evidence.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr double kFocal = 700.0;

struct Street {
  std::vector<double> db_s;
  std::vector<PairResult> pairs;
};

// Database cameras every `spacing_m` from `first_m` to `last_m`; the query at `l_m`, `offset_m`
// beside their line; every pair with `inliers` inliers and `parallax_deg` of parallax.
Street MakeStreet(double l_m,
                  double offset_m,
                  double first_m = 0.0,
                  double last_m = 8.0,
                  double spacing_m = 1.0,
                  int inliers = 100,
                  double parallax_deg = 4.0) {
  Street street;
  for (double s = first_m; s <= last_m + 1e-9; s += spacing_m) {
    PairResult p;
    p.db_index = static_cast<int>(street.db_s.size());
    p.valid = true;
    p.num_inliers = p.num_matches = inliers;
    p.parallax_deg = parallax_deg;
    p.signed_cot = (s - l_m) / offset_m;
    p.signed_distance = p.signed_cot / kFocal;
    p.distance = std::abs(p.signed_distance);
    street.db_s.push_back(s);
    street.pairs.push_back(p);
  }
  return street;
}

TEST(Evidence, ExactPairsGiveTheExactPosition) {
  const Street street = MakeStreet(4.3, 1.5);
  EvidenceOptions options;
  options.floor_sigma_m = 0.0;
  const AlongTrackMeasurement m = MeasureAlongTrack(street.pairs, street.db_s, kFocal, options);
  ASSERT_TRUE(m.valid) << m.failure;
  EXPECT_NEAR(m.l_m, 4.3, 1e-9);
  EXPECT_NEAR(m.lateral_offset_m, 1.5, 1e-9);
  EXPECT_EQ(m.num_used, 9);
  EXPECT_EQ(m.num_behind, 5);  // cameras at 0..4 m
  EXPECT_EQ(m.num_ahead, 4);
  for (PairVerdict v : m.verdicts) EXPECT_EQ(v, PairVerdict::kUsed);
  EXPECT_GT(m.sigma_m, 0.0);
  EXPECT_LT(m.sigma_m, 0.05);
}

// Past the route's end (a run of the suite's synth_beyond_ends, frame 345, 14 m beyond the last
// database camera): every camera behind the vehicle at nearly the same angle, so the line through
// them is flat and its intercept anywhere. A fit that puts l among the cameras contradicts their
// signs (the last one says the vehicle is ahead of it): that is no measurement, and never one
// inside the route.
TEST(Evidence, ALineThatPutsCamerasOnTheWrongSideIsNoMeasurement) {
  const std::vector<double> db_s = {76.0, 76.8, 77.6, 78.4, 79.191, 79.98};
  // The pairs' signed cotangents (a lateral offset of about 0.12 m: u = (s - l) / offset).
  const std::vector<double> u = {-108.84, -125.19, -461.31, -81.29, -7.90, -112.54};
  const std::vector<double> d = {0.01735, 0.02170, 0.02009, 0.02309, 0.00731, 0.02012};
  const std::vector<int> inliers = {81, 92, 94, 97, 44, 112};
  const std::vector<double> parallax = {2.81, 2.49, 2.48, 2.20, 2.87, 2.09};
  std::vector<PairResult> pairs;
  for (size_t j = 0; j < db_s.size(); ++j) {
    PairResult p;
    p.db_index = static_cast<int>(j);
    p.valid = true;
    p.num_inliers = inliers[j];
    p.num_matches = inliers[j] + 30;
    p.parallax_deg = parallax[j];
    p.signed_distance = -d[j];
    p.distance = d[j];
    p.signed_cot = u[j];
    pairs.push_back(p);
  }
  const AlongTrackMeasurement m = MeasureAlongTrack(pairs, db_s, kFocal, EvidenceOptions());
  if (m.valid) {
    // The vehicle is ahead of every camera: l beyond the last one.
    EXPECT_GT(m.l_m, db_s.back() - 2.0 * m.sigma_m) << "sigma " << m.sigma_m;
  } else {
    EXPECT_FALSE(m.failure.empty());
  }
}

// The failure seen on an unseen drive: a pair 2-3 spacings ahead with a near-zero d (its
// matches on a car driving ahead) must neither move the position nor count.
TEST(Evidence, ADegenerateEpipoleIsRefusedNotTheNearestFrame) {
  Street street = MakeStreet(4.3, 1.5);
  PairResult& ahead = street.pairs[7];  // 2.7 m ahead of the vehicle
  ahead.signed_cot = 0.02;
  ahead.num_inliers = 90;  // well supported: only its direction gives it away
  PairResult& weak = street.pairs[2];
  weak.num_inliers = 20;  // a fifth of the best: mostly matches on something else
  weak.signed_cot = -0.01;
  street.pairs[8].valid = false;
  street.pairs[8].failure = "too few matches";
  const AlongTrackMeasurement m =
      MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  ASSERT_TRUE(m.valid) << m.failure;
  EXPECT_NEAR(m.l_m, 4.3, 1e-6);
  EXPECT_EQ(m.verdicts[7], PairVerdict::kInconsistent);
  EXPECT_EQ(m.verdicts[2], PairVerdict::kWeakSupport);
  EXPECT_EQ(m.verdicts[8], PairVerdict::kFailed);
  EXPECT_EQ(m.num_used, 6);
  EXPECT_STREQ(PairVerdictName(PairVerdict::kInconsistent), "inconsistent with its neighbours");
}

TEST(Evidence, TooLittleEvidenceIsNoMeasurement) {
  Street street = MakeStreet(4.3, 1.5, 3.0, 4.0);  // two pairs
  AlongTrackMeasurement m = MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  EXPECT_FALSE(m.valid);
  EXPECT_EQ(m.failure, "too few pairs with support");

  // Directions without road geometry: the line's slope says the cameras are 100 m to the side.
  street = MakeStreet(4.3, 100.0);
  m = MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  EXPECT_FALSE(m.valid);
  EXPECT_EQ(m.failure, "the pairs' directions show no road geometry");

  // Every pair on a line of the wrong slope (d shrinking with the distance): no line at all.
  street = MakeStreet(4.3, -1.5);
  m = MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  EXPECT_FALSE(m.valid);

  EXPECT_FALSE(MeasureAlongTrack({}, {}, kFocal, EvidenceOptions()).valid);
  EvidenceOptions bad;
  bad.min_pairs = 1;
  EXPECT_THROW(bad.Check(), Error);
}

TEST(Evidence, LessSupportOrParallaxMeansALargerSigma) {
  EvidenceOptions options;
  options.floor_sigma_m = 0.0;
  const double strong =
      MeasureAlongTrack(MakeStreet(4.3, 1.5).pairs, MakeStreet(4.3, 1.5).db_s, kFocal, options)
          .sigma_m;
  const Street few = MakeStreet(4.3, 1.5, 0.0, 8.0, 1.0, 25);
  const Street flat = MakeStreet(4.3, 1.5, 0.0, 8.0, 1.0, 100, 1.0);
  EXPECT_NEAR(MeasureAlongTrack(few.pairs, few.db_s, kFocal, options).sigma_m, 2 * strong,
              1e-3 * strong);
  EXPECT_NEAR(MeasureAlongTrack(flat.pairs, flat.db_s, kFocal, options).sigma_m, 4 * strong,
              1e-3 * strong);
}

// Calibration: with the direction noise the model assumes (σ_φ = σ_px / (f p √N) on the angle
// of each baseline), |l̂ - l| <= 2σ in about 95 % of trials, and not far more (σ not inflated).
TEST(Evidence, SigmaIsCalibratedUnderTheModelsNoise) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> position(3.0, 5.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  EvidenceOptions options;
  options.floor_sigma_m = 0.0;
  int within = 0, valid = 0;
  constexpr int kTrials = 400;
  for (int trial = 0; trial < kTrials; ++trial) {
    const double l = position(rng);
    Street street = MakeStreet(l, 1.5, 0.0, 8.0, 1.0, 60, 3.0);
    const double sigma_angle =
        options.feature_sigma_px / (kFocal * 3.0 * M_PI / 180 * std::sqrt(60));
    for (PairResult& p : street.pairs) {
      const double angle = std::atan2(1.0, p.signed_cot) + sigma_angle * normal(rng);
      p.signed_cot = 1.0 / std::tan(angle);
    }
    const AlongTrackMeasurement m = MeasureAlongTrack(street.pairs, street.db_s, kFocal, options);
    if (!m.valid) continue;
    ++valid;
    within += std::abs(m.l_m - l) <= 2 * m.sigma_m;
  }
  EXPECT_GE(valid, kTrials * 99 / 100);
  const double share = static_cast<double>(within) / valid;
  EXPECT_GE(share, 0.90);
  EXPECT_LE(share, 0.995);
}

// A frame 13.8 m before the route's first camera sees every camera far ahead: their directions
// (large u, large sigma) fix no position. One wrong essential matrix with a confident direction
// (u = -1 at the first camera, 13 degrees of parallax: repeated texture) lies on a line through
// all of them, and alone would place the frame at the route's start with a sigma of 0.13 m. The
// pairs are those of a frame of the scenario suite (synth_beyond_ends) that did.
TEST(Evidence, OnePairDoesNotDecideThePosition) {
  struct Row {
    double s, u, parallax_deg;
    int inliers;
  };
  const std::vector<Row> rows = {{0.0, -0.9695, 13.335, 22}, {0.8, 14.705, 1.150, 26},
                                 {3.2, 19.996, 1.004, 22},   {4.0, 21.668, 1.158, 23},
                                 {4.8, -1.675, 17.739, 21},  {5.6, 18.414, 1.352, 20}};
  Street street;
  for (const Row& row : rows) {
    PairResult p;
    p.db_index = static_cast<int>(street.db_s.size());
    p.valid = true;
    p.num_inliers = row.inliers;
    p.num_matches = 2 * row.inliers;
    p.parallax_deg = row.parallax_deg;
    p.signed_cot = row.u;
    street.db_s.push_back(row.s);
    street.pairs.push_back(p);
  }
  const AlongTrackMeasurement m =
      MeasureAlongTrack(street.pairs, street.db_s, 600.0, EvidenceOptions());
  ASSERT_EQ(m.verdicts[0], PairVerdict::kUsed) << "the wrong pair fits the line: the case tested";
  ASSERT_TRUE(m.valid) << m.failure;  // a measurement, with an honest sigma
  EXPECT_LT(m.model_sigma_m, 0.3) << "the fit's own sigma trusts the wrong pair";
  EXPECT_NEAR(m.l_m, 0.2, 0.1);  // the wrong pair's position
  EXPECT_GT(m.sigma_m, 2.0);
  EXPECT_LE(std::abs(m.l_m + 13.8), 3 * m.sigma_m) << "sigma " << m.sigma_m;
}

// Three pairs whose line only exists with one of them (the other two at the same place): no
// measurement, whatever the fit's covariance says.
TEST(Evidence, ALineThatOnePairAloneMakesIsNoMeasurement) {
  Street street = MakeStreet(1.0, 1.0, 0.0, 2.0, 1.0);  // cameras at 0, 1, 2
  street.db_s[2] = 1.0;                                 // the third beside the second
  street.pairs[2].signed_cot = 0.001;
  const AlongTrackMeasurement m =
      MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  EXPECT_EQ(m.num_used, 3);
  EXPECT_FALSE(m.valid);
  EXPECT_EQ(m.failure, "one pair decides the line");
}

// Agreeing pairs keep the fit's sigma: the jackknife adds nothing where no pair stands out.
TEST(Evidence, AgreeingPairsKeepTheModelSigma) {
  const Street street = MakeStreet(4.3, 1.5);
  const AlongTrackMeasurement m =
      MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  ASSERT_TRUE(m.valid) << m.failure;
  EXPECT_NEAR(m.sigma_m, m.model_sigma_m, 1e-12);
}

// A camera turned by more than the gate (a car turning into the street) gives no evidence.
TEST(Evidence, PairsTurnedAwayAreNoEvidence) {
  Street street = MakeStreet(4.3, 1.5);
  for (int k : {3, 4, 5}) street.pairs[k].heading_deg = (k == 4 ? -70.0 : 55.0);
  street.pairs[4].signed_cot = -0.5;  // and wrong: it would move the line
  const AlongTrackMeasurement gated =
      MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions(), 40.0);
  ASSERT_TRUE(gated.valid) << gated.failure;
  for (int k : {3, 4, 5}) EXPECT_EQ(gated.verdicts[k], PairVerdict::kTurnedAway) << k;
  EXPECT_EQ(gated.num_used, 6);
  EXPECT_NEAR(gated.l_m, 4.3, 1e-9);
  EXPECT_STREQ(PairVerdictName(PairVerdict::kTurnedAway), "turned away from the database camera");
  // Without the gate (the default) the turned pairs count.
  const AlongTrackMeasurement open =
      MeasureAlongTrack(street.pairs, street.db_s, kFocal, EvidenceOptions());
  EXPECT_EQ(open.verdicts[3], PairVerdict::kUsed);
}

}  // namespace
}  // namespace epiloc
