// The radial term's search (SearchRadialTerm) on measurements with known answers; the whole
// calibration (VO and anchors) on the KITTI-like synthetic camera is in
// tests/cli/pipeline_structure_test.cc, on the shared drive in structure_anchor_kitti_test.cc.
#include "epiloc/anchor/radial_calibration.h"

#include <cmath>

#include <gtest/gtest.h>

#include "test_util.h"

namespace epiloc {
namespace {

// A measurement whose trend is `trend(term)`, over 60 m of ok anchors.
std::function<RadialCalibrationRun(double)> Measuring(std::function<double(double)> trend,
                                                      std::vector<double>* terms = nullptr) {
  return [trend, terms](double term) {
    if (terms) terms->push_back(term);
    RadialCalibrationRun run;
    run.term = term;
    VoScaleTrend t;
    t.anchors = 16;
    t.distance_m = 60.0;
    t.percent_per_100m = trend(term);
    run.trend = t;
    run.ok_anchors = 16;
    run.anchors = 16;
    return run;
  };
}

// KITTI's camera 1 as measured (README): -29 % per 100 m as calibrated, -3.7 % at k2 = +0.017;
// the secant's straight line through them puts the root at +0.0194; a mild curvature on top.
TEST(RadialCalibration, SecantFindsTheTermWithoutTrend) {
  const double root = 0.0194;
  const auto trend = [&](double k) { return 1500.0 * (k - root) + 8000.0 * (k - root) * (k - root); };
  RadialCalibrationOptions options;
  options.term = RadialCalibrationOptions::Term::kK2;
  options.tolerance_percent_per_100m = 0.5;
  std::vector<double> terms;
  const RadialCalibrationResult result = SearchRadialTerm(0.0, options, Measuring(trend, &terms));
  ASSERT_TRUE(result.converged) << result.message;
  EXPECT_NEAR(result.term, root, 0.5 / 1500.0 * 1.5);
  ASSERT_GE(terms.size(), 3u);
  EXPECT_LE(terms.size(), 4u);
  EXPECT_EQ(terms[0], 0.0);                   // the calibration's own term first
  EXPECT_NEAR(terms[1], options.first_step, 1e-12);  // then a step against the trend's sign
  EXPECT_EQ(result.runs[result.best_run].term, result.term);
  // Already within the tolerance: one run, the term unchanged.
  const RadialCalibrationResult unchanged = SearchRadialTerm(root, options, Measuring(trend));
  EXPECT_TRUE(unchanged.converged);
  EXPECT_EQ(unchanged.runs.size(), 1u);
  EXPECT_EQ(unchanged.term, root);
  // A trend of the other sign steps the other way, from a calibration that already has a term.
  const RadialCalibrationResult from_above = SearchRadialTerm(0.05, options, Measuring(trend));
  ASSERT_TRUE(from_above.converged) << from_above.message;
  EXPECT_LT(from_above.runs[1].term, 0.05);
  EXPECT_NEAR(from_above.term, root, 0.5 / 1500.0 * 1.5);
}

TEST(RadialCalibration, StopsWhereTheMeasurementCannotTell) {
  RadialCalibrationOptions options;
  // No trend at the second run (too few ok anchors): stops, the first run is the best.
  int calls = 0;
  const RadialCalibrationResult lost = SearchRadialTerm(0.0, options, [&](double term) {
    RadialCalibrationRun run = Measuring([](double k) { return 1500.0 * (k - 0.02); })(term);
    if (++calls == 2) {
      run.trend.reset();
      run.message = "1 of 16 anchors ok";
    }
    return run;
  });
  EXPECT_FALSE(lost.converged);
  EXPECT_EQ(lost.runs.size(), 2u);
  EXPECT_EQ(lost.best_run, 0);
  EXPECT_EQ(lost.term, 0.0);
  EXPECT_NE(lost.message.find("1 of 16 anchors ok"), std::string::npos) << lost.message;
  // A trend the term does not move: two equal measurements, no secant.
  const RadialCalibrationResult flat =
      SearchRadialTerm(0.0, options, Measuring([](double) { return -20.0; }));
  EXPECT_FALSE(flat.converged);
  EXPECT_EQ(flat.runs.size(), 2u);
  EXPECT_NE(flat.message.find("same trend"), std::string::npos) << flat.message;
  // A root beyond max_change: the search stops at the bound, not converged.
  options.max_change = 0.03;
  std::vector<double> terms;
  const RadialCalibrationResult far =
      SearchRadialTerm(0.0, options, Measuring([](double k) { return 500.0 * (k - 0.2); }, &terms));
  EXPECT_FALSE(far.converged);
  for (const double t : terms) EXPECT_LE(t, 0.03 + 1e-12);
  EXPECT_NE(far.message.find("beyond"), std::string::npos) << far.message;
  // Each step at most max_step.
  options.max_change = 0.06;
  options.max_step = 0.015;
  terms.clear();
  SearchRadialTerm(0.0, options, Measuring([](double k) { return 100.0 * (k - 0.05); }, &terms));
  for (size_t i = 1; i < terms.size(); ++i) EXPECT_LE(std::abs(terms[i] - terms[i - 1]), 0.015 + 1e-12);
  // Bad options.
  options.max_runs = 1;
  ExpectError([&] { SearchRadialTerm(0.0, options, Measuring([](double) { return 0.0; })); },
              {"max_runs"});
}

}  // namespace
}  // namespace epiloc
