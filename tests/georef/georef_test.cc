#include "epiloc/georef/georef.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/geo/geodetic.h"
#include "epiloc/georef/similarity.h"
#include "test_util.h"

namespace epiloc {
namespace {

Eigen::Quaterniond AxisAngle(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis.normalized()));
}

double AngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return RotationDifferenceDeg(a, b);
}

// enu_from_cam of a level camera (x right, y down, z forward) looking along `forward_in_enu`.
Eigen::Quaterniond LevelCamera(const Eigen::Vector3d& forward_in_enu) {
  const Eigen::Vector3d f = Eigen::Vector3d(forward_in_enu.x(), forward_in_enu.y(), 0).normalized();
  const Eigen::Vector3d down(0, 0, -1);
  const Eigen::Vector3d right = down.cross(f);  // x = y cross z
  Eigen::Matrix3d r;
  r.col(0) = right;
  r.col(1) = down;
  r.col(2) = f;
  return Eigen::Quaterniond(r);
}

AnchorPair MakeAnchor(double t,
                      const Rigid3d& vo_from_cam,
                      const Eigen::Vector3d& centre_in_enu,
                      const Eigen::Quaterniond& enu_from_cam) {
  AnchorPair a;
  a.frame = static_cast<frame_t>(std::lround(t * 10));
  a.timestamp_s = t;
  a.vo_from_cam = vo_from_cam;
  a.centre_in_enu = centre_in_enu;
  a.enu_from_cam = enu_from_cam;
  return a;
}

// A drive along a left-hand arc (radius 150 m, 1 m per frame at 10 Hz, rising 2 %) and a
// monocular trajectory of it whose scale drifts by `scale_drift` over the drive and whose frame
// turns by `yaw_drift_deg` (about the VO's vertical) over it: the VO steps are the true steps
// rotated into the drifting VO frame and scaled by the drifting scale.
struct SyntheticRun {
  std::vector<double> times;
  std::vector<Eigen::Vector3d> centre_in_enu;
  std::vector<Eigen::Quaterniond> enu_from_cam;
  std::vector<Rigid3d> vo_from_cam;
};

SyntheticRun MakeRun(int frames, double scale_drift, double yaw_drift_deg) {
  SyntheticRun run;
  const double radius = 150.0;
  const double vo_units_per_m = 0.2;  // the VO's unit is 5 m at the start
  // enu_from_vo at the start: the VO frame is the first camera frame, rotated somewhat.
  const Eigen::Quaterniond enu_from_vo0 =
      LevelCamera(Eigen::Vector3d(1, 0, 0)) * AxisAngle(0.1, Eigen::Vector3d(1, 2, 3));
  Eigen::Vector3d x_vo(0.3, -0.2, 0.1);
  for (int i = 0; i < frames; ++i) {
    const double s = i;  // metres
    const Eigen::Vector3d centre(radius * std::sin(s / radius), radius * (1 - std::cos(s / radius)),
                                 1.6 + 0.02 * s);
    const Eigen::Vector3d forward(std::cos(s / radius), std::sin(s / radius), 0.0);
    const double w = static_cast<double>(i) / frames;
    const Eigen::Quaterniond enu_from_vo =
        enu_from_vo0 * AxisAngle(yaw_drift_deg * w * M_PI / 180, Eigen::Vector3d(0, 1, 0));
    if (i > 0) {
      const double k = vo_units_per_m * (1.0 + scale_drift * w);
      x_vo += k * (enu_from_vo.conjugate() * (centre - run.centre_in_enu.back()));
    }
    run.times.push_back(100.0 + 0.1 * i);
    run.centre_in_enu.push_back(centre);
    run.enu_from_cam.push_back(LevelCamera(forward));
    run.vo_from_cam.push_back(Rigid3d(enu_from_vo.conjugate() * run.enu_from_cam.back(), x_vo));
  }
  return run;
}

std::vector<AnchorPair> AnchorsEvery(const SyntheticRun& run, int step) {
  std::vector<AnchorPair> anchors;
  for (size_t i = 0; i < run.times.size(); i += static_cast<size_t>(step)) {
    anchors.push_back(
        MakeAnchor(run.times[i], run.vo_from_cam[i], run.centre_in_enu[i], run.enu_from_cam[i]));
  }
  return anchors;
}

// Max and mean position error of a transform over all frames of the run.
struct Errors {
  double max_m = 0.0;
  double mean_m = 0.0;
};
Errors ErrorsOver(const GeorefTransform& transform, const SyntheticRun& run) {
  Errors e;
  for (size_t i = 0; i < run.times.size(); ++i) {
    const double d =
        (transform.Map(run.times[i], run.vo_from_cam[i]).translation - run.centre_in_enu[i]).norm();
    e.max_m = std::max(e.max_m, d);
    e.mean_m += d / static_cast<double>(run.times.size());
  }
  return e;
}

TEST(Georef, MethodNames) {
  for (const GeorefMethod m :
       {GeorefMethod::kPaper, GeorefMethod::kSim3, GeorefMethod::kPiecewise}) {
    EXPECT_EQ(ParseGeorefMethod(GeorefMethodName(m)), m);
  }
  EXPECT_EQ(ParseGeorefMethods("all").size(), 3u);
  const std::vector<GeorefMethod> two = ParseGeorefMethods("sim3, paper,sim3");
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0], GeorefMethod::kSim3);
  EXPECT_EQ(two[1], GeorefMethod::kPaper);
  ExpectError([] { ParseGeorefMethod("icp"); },
              {"unknown georeferencing method 'icp'", "piecewise"});
  GeorefOptions options;
  options.max_gap_s = 0.0;
  ExpectError([&] { options.Check(); }, {"--max-gap-s"});
  options = GeorefOptions();
  options.paper_second_anchor = 0;
  ExpectError([&] { options.Check(); }, {"--paper-second-anchor"});
  options = GeorefOptions();
  options.end_drift_reach_m = -1.0;
  ExpectError([&] { options.Check(); }, {"--end-drift-reach-m must be >= 0"});
}

// Eq. 5-7 by hand. VO frame = the first camera's frame, VO origin at the first anchor. The
// first camera looks north: enu_from_cam = [x east, y down, z north]. The second anchor is 30 m
// east, 40 m north and 0.5 m up (travel direction u = (0.6, 0.8, 0), 50 m along it). The VO
// moved x_n = (3, 0.2, 4): R x_n = (3, 4, -0.2), 5 units along u, so scale = 50 / 5 = 10 m per
// unit. The full 3-D ratio of eq. 6 would give |(30, 40, 0.5)| / |(3, 4, -0.2)| = 9.9925; the
// travel-direction variant ignores the VO's vertical (and lateral) error.
TEST(Georef, PaperTwoAnchorConversionByHand) {
  Eigen::Matrix3d r0;
  r0 << 1, 0, 0,  //
      0, 0, 1,    //
      0, -1, 0;
  const Eigen::Quaterniond enu_from_cam0(r0);
  const Eigen::Vector3d x0_enu(10, 20, 1.6);
  const Eigen::Vector3d xn_enu = x0_enu + Eigen::Vector3d(30, 40, 0.5);
  const Rigid3d vo0(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const Rigid3d von(AxisAngle(0.2, Eigen::Vector3d::UnitY()), Eigen::Vector3d(3, 0.2, 4));
  // A middle anchor that disagrees: only the first and the chosen second anchor count.
  const Rigid3d vom(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 1));
  const std::vector<AnchorPair> anchors = {
      MakeAnchor(0.0, vo0, x0_enu, enu_from_cam0),
      MakeAnchor(1.0, vom, Eigen::Vector3d(500, 500, 500), enu_from_cam0),
      MakeAnchor(2.0, von, xn_enu, enu_from_cam0 * AxisAngle(0.5, Eigen::Vector3d::UnitX()))};
  const GeorefTransform transform = PaperTransform(anchors);
  ASSERT_EQ(transform.intervals.size(), 1u);
  const Sim3d& sim = transform.intervals[0];
  EXPECT_NEAR(sim.scale, 10.0, 1e-12);
  EXPECT_LT(AngleDeg(sim.rotation, enu_from_cam0), 1e-12);
  EXPECT_LT((sim.translation - x0_enu).norm(), 1e-12);
  // X = s R (x - x_0) + X_0 for any VO point; e.g. (1, 0, 2) -> R: (1, 2, 0) -> (20, 40, 1.6).
  const Rigid3d mapped =
      transform.Map(0.5, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 2)));
  EXPECT_LT((mapped.translation - Eigen::Vector3d(20, 40, 1.6)).norm(), 1e-12);
  // The first anchor is hit exactly; the second only along the travel direction: s R x_n + X_0 =
  // (40, 60, -0.4) against (40, 60, 2.1) (the VO's vertical error scaled).
  EXPECT_LT((transform.Map(0.0, vo0).translation - x0_enu).norm(), 1e-12);
  const Rigid3d at_n = transform.Map(2.0, von);
  EXPECT_LT((at_n.translation - Eigen::Vector3d(40, 60, -0.4)).norm(), 1e-12);
  // Orientation: enu_from_cam = R R_vo.
  EXPECT_LT(AngleDeg(at_n.rotation, enu_from_cam0 * von.rotation), 1e-12);
  // The middle anchor as the second: u = (490, 480, 0) normalised, R x_m = (1, 1, 0).
  const GeorefTransform middle = PaperTransform(anchors, 1);
  const Eigen::Vector3d chord(490, 480, 0);
  const double expected = chord.norm() / (chord.normalized().dot(Eigen::Vector3d(1, 1, 0)));
  EXPECT_NEAR(middle.intervals[0].scale, expected, 1e-9);
}

// A VO trajectory that is the truth up to a similarity (no drift): the paper's conversion is
// exact everywhere, and it does not depend on the VO's frame (rotating, shifting and scaling the
// VO world gives the same result).
TEST(Georef, PaperIsExactWithoutDriftAndIndependentOfTheVoFrame) {
  const SyntheticRun run = MakeRun(120, 0.0, 0.0);
  const std::vector<AnchorPair> anchors = AnchorsEvery(run, 40);
  const GeorefTransform transform = PaperTransform(anchors);
  const Errors e = ErrorsOver(transform, run);
  EXPECT_LT(e.max_m, 1e-9);
  EXPECT_NEAR(transform.intervals[0].scale, 5.0, 1e-9);
  for (size_t i = 0; i < run.times.size(); i += 7) {
    EXPECT_LT(
        AngleDeg(transform.Map(run.times[i], run.vo_from_cam[i]).rotation, run.enu_from_cam[i]),
        1e-6);
  }
  // Another VO world: x' = g Q x + c, R_vo' = Q R_vo.
  Sim3d vo2_from_vo;
  vo2_from_vo.scale = 0.37;
  vo2_from_vo.rotation = AxisAngle(2.0, Eigen::Vector3d(-1, 4, 2));
  vo2_from_vo.translation = Eigen::Vector3d(7, -3, 11);
  SyntheticRun moved = run;
  for (Rigid3d& pose : moved.vo_from_cam) pose = vo2_from_vo.MapPose(pose);
  const GeorefTransform transform2 = PaperTransform(AnchorsEvery(moved, 40));
  EXPECT_LT(ErrorsOver(transform2, moved).max_m, 1e-9);
}

TEST(Georef, PaperRejectsUnusableAnchors) {
  const SyntheticRun run = MakeRun(60, 0.0, 0.0);
  std::vector<AnchorPair> anchors = AnchorsEvery(run, 30);
  ExpectError([&] { PaperTransform({anchors[0]}); }, {"paper: needs two anchors, got 1"});
  ExpectError([&] { PaperTransform(anchors, 5); }, {"second anchor 5 out of range"});
  std::vector<AnchorPair> no_orientation = anchors;
  no_orientation[0].enu_from_cam.reset();
  ExpectError([&] { PaperTransform(no_orientation); }, {"no orientation", "paper"});
  // Standing still (the second anchor straight above the first): no travel direction.
  std::vector<AnchorPair> standing = anchors;
  standing[1].centre_in_enu = standing[0].centre_in_enu + Eigen::Vector3d(0, 0, 0.5);
  ExpectError([&] { PaperTransform(standing); }, {"same horizontal position"});
  // The VO went backwards: a negative scale.
  std::vector<AnchorPair> backwards = anchors;
  backwards[1].vo_from_cam.translation =
      2 * backwards[0].vo_from_cam.translation - backwards[1].vo_from_cam.translation;
  ExpectError([&] { PaperTransform(backwards); }, {"no positive scale"});
}

TEST(Georef, Sim3IsExactWithoutDriftAndNeedsThreeAnchorsOffALine) {
  const SyntheticRun run = MakeRun(120, 0.0, 0.0);
  const GeorefTransform transform = Sim3Transform(AnchorsEvery(run, 30));
  EXPECT_LT(ErrorsOver(transform, run).max_m, 1e-9);
  EXPECT_NEAR(transform.intervals[0].scale, 5.0, 1e-9);
  std::vector<AnchorPair> anchors = AnchorsEvery(run, 50);
  ASSERT_EQ(anchors.size(), 3u);
  ExpectError([&] { Sim3Transform({anchors[0], anchors[1]}); }, {"at least three anchors, got 2"});
  // Anchors on one line of the VO frame (a straight drive): their orientations fix the rotation
  // about it; without orientations it is undetermined.
  for (size_t i = 0; i < anchors.size(); ++i) {
    anchors[i].vo_from_cam.translation = Eigen::Vector3d(0, 0, static_cast<double>(i));
  }
  EXPECT_NO_THROW(Sim3Transform(anchors));
  for (AnchorPair& a : anchors) a.enu_from_cam.reset();
  ExpectError([&] { Sim3Transform(anchors); }, {"lie on one line"});
}

// Nearly straight anchors (0.1 units off a 110-unit line) with 2 cm noise on their centres:
// positions alone leave the roll about the line to the noise; the anchors' orientations pin it.
TEST(Georef, Sim3UsesAnchorOrientationsOnANearlyStraightDrive) {
  const SyntheticRun run = MakeRun(120, 0.0, 0.0);
  std::vector<AnchorPair> anchors = AnchorsEvery(run, 10);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.02);
  const Sim3d truth = [&] {
    const GeorefTransform exact = Sim3Transform(anchors);
    return exact.intervals[0];
  }();
  for (size_t i = 0; i < anchors.size(); ++i) {
    // Rebuild the anchors on a line of the VO frame, consistent with `truth`.
    const Eigen::Vector3d x(0.1 * std::sin(static_cast<double>(i)), 0.0, 10.0 * i);
    anchors[i].vo_from_cam.translation = x;
    anchors[i].centre_in_enu = truth * x + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    anchors[i].enu_from_cam = truth.rotation * anchors[i].vo_from_cam.rotation;
  }
  const GeorefTransform fit = Sim3Transform(anchors);
  const double angle_deg = RotationDifferenceDeg(fit.intervals[0].rotation, truth.rotation);
  EXPECT_LT(angle_deg, 0.1);
  std::vector<Eigen::Vector3d> source, target;
  for (const AnchorPair& a : anchors) {
    source.push_back(a.vo_from_cam.translation);
    target.push_back(a.centre_in_enu);
  }
  const auto positions_only = FitSim3(source, target);
  ASSERT_TRUE(positions_only.has_value());
  EXPECT_GT(RotationDifferenceDeg(positions_only->rotation, truth.rotation), 3 * angle_deg);
  EXPECT_NEAR(fit.intervals[0].scale, truth.scale, 0.01 * truth.scale);
}

// Scale drifting by 50 % over 200 m and the VO frame turning by 3 degrees: piecewise
// re-anchoring every 20 m is exact at the anchors (positions and orientations) and stays within
// ~0.12 m between them, where one similarity (sim3) or the paper's two anchors are off by
// metres.
TEST(Georef, PiecewiseAbsorbsScaleDrift) {
  const SyntheticRun run = MakeRun(201, 0.5, 3.0);
  const std::vector<AnchorPair> anchors = AnchorsEvery(run, 20);
  ASSERT_EQ(anchors.size(), 11u);
  const GeorefTransform transform = PiecewiseTransform(anchors);
  ASSERT_EQ(transform.times.size(), 11u);
  ASSERT_EQ(transform.intervals.size(), 10u);
  // Scales follow the drift: 5 m per unit at the start, 5 / 1.5 at the end.
  EXPECT_NEAR(transform.intervals.front().scale, 5.0 / 1.025, 0.05);
  EXPECT_NEAR(transform.intervals.back().scale, 5.0 / 1.475, 0.05);
  for (const AnchorPair& a : anchors) {
    const Rigid3d mapped = transform.Map(a.timestamp_s, a.vo_from_cam);
    EXPECT_LT((mapped.translation - a.centre_in_enu).norm(), 1e-9) << "anchor t " << a.timestamp_s;
    EXPECT_LT(AngleDeg(mapped.rotation, *a.enu_from_cam), 1e-6);
  }
  // Continuity: both neighbouring intervals map an inner anchor's VO centre onto it.
  for (size_t k = 1; k + 1 < anchors.size(); ++k) {
    EXPECT_LT(
        (transform.intervals[k - 1] * anchors[k].vo_from_cam.translation - anchors[k].centre_in_enu)
            .norm(),
        1e-9);
  }
  const Errors piecewise = ErrorsOver(transform, run);
  const Errors sim3 = ErrorsOver(Sim3Transform(anchors), run);
  const Errors paper = ErrorsOver(PaperTransform(anchors), run);
  std::printf(
      "max / mean error: piecewise %.3f / %.3f m, sim3 %.3f / %.3f m, paper %.3f / %.3f m\n",
      piecewise.max_m, piecewise.mean_m, sim3.max_m, sim3.mean_m, paper.max_m, paper.mean_m);
  // A scale drifting linearly by dk over an interval of length L bends the positions by at most
  // L dk / 8 (mid-interval): 20 m * 5 % / 8 = 0.125 m. Measured: max 0.122 m, mean 0.067 m;
  // sim3 6.4 / 2.7 m, paper 13.7 / 8.2 m.
  EXPECT_LT(piecewise.max_m, 0.15);
  EXPECT_LT(piecewise.mean_m, 0.08);
  EXPECT_GT(sim3.max_m, 10 * piecewise.max_m);
  EXPECT_GT(paper.max_m, 10 * piecewise.max_m);
  // Orientation between anchors: within the VO frame's turn over one interval (0.3 deg).
  for (size_t i = 0; i < run.times.size(); ++i) {
    EXPECT_LT(
        AngleDeg(transform.Map(run.times[i], run.vo_from_cam[i]).rotation, run.enu_from_cam[i]),
        0.3);
  }
}

TEST(Georef, PiecewiseSkipsCloseAnchorsAndRejectsAStandingVo) {
  const SyntheticRun run = MakeRun(101, 0.0, 0.0);
  std::vector<AnchorPair> anchors = AnchorsEvery(run, 10);
  // An anchor 0.5 m after another (standing, or anchors too dense): skipped by default.
  std::vector<AnchorPair> dense = anchors;
  AnchorPair close = dense[3];
  close.timestamp_s += 0.05;
  close.vo_from_cam.translation +=
      0.05 * (anchors[4].vo_from_cam.translation - anchors[3].vo_from_cam.translation);
  close.centre_in_enu += 0.05 * (anchors[4].centre_in_enu - anchors[3].centre_in_enu);
  dense.insert(dense.begin() + 4, close);
  EXPECT_EQ(PiecewiseTransform(dense).times.size(), anchors.size());
  EXPECT_EQ(PiecewiseTransform(dense, 0.1).times.size(), anchors.size() + 1);
  ExpectError(
      [&] {
        PiecewiseTransform({anchors[0], close}, 1000.0);
      },
      {"needs two anchors at least 1000 m apart, got 1 of 2"});
  std::vector<AnchorPair> no_orientation = anchors;
  no_orientation[2].enu_from_cam.reset();
  ExpectError([&] { PiecewiseTransform(no_orientation); }, {"no orientation", "piecewise"});
  // The VO stood still while the anchors moved.
  std::vector<AnchorPair> standing = anchors;
  standing[5].vo_from_cam.translation = standing[4].vo_from_cam.translation;
  ExpectError([&] { PiecewiseTransform(standing); }, {"the VO did not move"});
}

// Anchors that carry their own scale of the trajectory (structure anchors): inside each interval
// the scale goes from one anchor's to the next's, and beyond the end anchors the trajectory goes
// on with the end anchor's rotation and scale; scales far from the chords' (another trajectory's)
// are not taken, and those in other units near the chords' are brought to the trajectory's.
TEST(Georef, PiecewiseTakesTheAnchorsOwnScalesInsideAndBeyondThem) {
  const int frames = 201;
  const SyntheticRun run = MakeRun(frames, 0.5, 3.0);
  // Anchors every 20 m from frame 20 to 180: 20 frames to extrapolate at either end.
  std::vector<AnchorPair> plain;
  for (size_t i = 20; i <= 180; i += 20) {
    plain.push_back(
        MakeAnchor(run.times[i], run.vo_from_cam[i], run.centre_in_enu[i], run.enu_from_cam[i]));
  }
  const auto with_scales = [&](double unit) {
    std::vector<AnchorPair> anchors = plain;
    for (size_t k = 0; k < anchors.size(); ++k) {
      // Metres per VO unit at the anchor's frame (MakeRun's drifting scale).
      const double w = static_cast<double>(20 + 20 * k) / frames;
      anchors[k].scale_m_per_unit = unit / (0.2 * (1.0 + 0.5 * w));
    }
    return anchors;
  };
  const GeorefTransform without = PiecewiseTransform(plain);
  const GeorefTransform with = PiecewiseTransform(with_scales(1.0));
  const GeorefTransform other = PiecewiseTransform(with_scales(3.0));
  // Scales in units 10 % off (within the check): brought to the trajectory's, nothing changes.
  const GeorefTransform units = PiecewiseTransform(with_scales(1.1));
  EXPECT_TRUE(without.ramps.empty());
  EXPECT_EQ(with.ramps.size(), with.intervals.size());
  EXPECT_TRUE(other.ramps.empty());
  // Inside (frames 20-180) and beyond the ends (0-19, 181-200), the largest error.
  const auto errors = [&](const GeorefTransform& transform) {
    double inside = 0.0, beyond = 0.0;
    for (size_t i = 0; i < run.times.size(); ++i) {
      const double d =
          (transform.Map(run.times[i], run.vo_from_cam[i]).translation - run.centre_in_enu[i])
              .norm();
      (i >= 20 && i <= 180 ? inside : beyond) = std::max(i >= 20 && i <= 180 ? inside : beyond, d);
    }
    return std::make_pair(inside, beyond);
  };
  const auto [inside_without, beyond_without] = errors(without);
  const auto [inside_with, beyond_with] = errors(with);
  const auto [inside_other, beyond_other] = errors(other);
  const auto [inside_units, beyond_units] = errors(units);
  EXPECT_NEAR(inside_units, inside_with, 1e-9);
  EXPECT_NEAR(beyond_units, beyond_with, 1e-9);
  std::printf(
      "max error inside / beyond the anchors: chord scales %.3f / %.3f m, the anchors' own "
      "%.3f / %.3f m, another trajectory's %.3f / %.3f m\n",
      inside_without, beyond_without, inside_with, beyond_with, inside_other, beyond_other);
  // Inside: L dk / 8 = 20 m * 5 % / 8 = 0.125 m with chord scales; with the anchors' scales only
  // the scale's curvature (1 / (1 + 0.5 w) is not linear) and the VO frame's turn remain.
  EXPECT_GT(inside_without, 0.1);
  EXPECT_LT(inside_with, 0.2 * inside_without);
  // Beyond: 20 m with the end interval's mean scale, 2.5 % off at the end anchor and drifting
  // on, against the end anchor's own scale, drifting on.
  EXPECT_LT(beyond_with, 0.6 * beyond_without);
  // Both stay exact at the anchors.
  for (const AnchorPair& a : with_scales(1.0)) {
    EXPECT_LT((with.Map(a.timestamp_s, a.vo_from_cam).translation - a.centre_in_enu).norm(), 1e-9);
  }
  // Another trajectory's scales (three times its units): the chord scales as without; the ends
  // take the end anchors' rotation either way.
  EXPECT_NEAR(inside_other, inside_without, 1e-12);
  EXPECT_NEAR(beyond_other, beyond_without, 1e-12);
  // An anchor without a scale: its intervals keep a constant scale.
  std::vector<AnchorPair> partial = with_scales(1.0);
  partial[4].scale_m_per_unit.reset();
  const GeorefTransform some = PiecewiseTransform(partial);
  ASSERT_EQ(some.ramps.size(), some.intervals.size());
  EXPECT_EQ(some.ramps[3].start, 1.0);
  EXPECT_EQ(some.ramps[4].end, 1.0);
  EXPECT_NE(some.ramps[5].start, 1.0);
}

// Anchors that also carry the VO's scale drift their fit found (structure anchors), with a reach
// given (off by default): beyond the end anchors the trajectory goes on with the scale drifting as
// it did there for the reach, and held beyond; another trajectory's drift is not taken.
TEST(Georef, PiecewiseFollowsTheEndAnchorsDriftBeyondThem) {
  const int frames = 241;
  // The scale falls by a third over the drive (a monocular VO's drift of 1.4-2 % per 10 m).
  const double drift = 0.5;
  const SyntheticRun run = MakeRun(frames, drift, 0.0);
  // Anchors every 20 m from frame 40 to 200: 40 frames (metres) to extrapolate at either end.
  const auto anchors = [&](double unit, bool with_drift) {
    std::vector<AnchorPair> out;
    for (size_t i = 40; i <= 200; i += 20) {
      AnchorPair a =
          MakeAnchor(run.times[i], run.vo_from_cam[i], run.centre_in_enu[i], run.enu_from_cam[i]);
      // MakeRun's scale, metres per VO unit, 1 / (0.2 (1 + drift w)) at w = i / frames (1 m per
      // frame), and its relative change per metre of road: -drift / frames / (1 + drift w).
      const double w = static_cast<double>(i) / frames;
      a.scale_m_per_unit = unit / (0.2 * (1.0 + drift * w));
      if (with_drift) a.scale_drift_per_m = -drift / frames / (1.0 + drift * w);
      out.push_back(a);
    }
    return out;
  };
  // The largest error before the first and after the last anchor, and within 20 m of them.
  struct Beyond {
    double near = 0.0, far = 0.0;
  };
  const auto beyond = [&](const GeorefTransform& transform) {
    Beyond b;
    for (size_t i = 0; i < run.times.size(); ++i) {
      if (i >= 40 && i <= 200) continue;
      const double d =
          (transform.Map(run.times[i], run.vo_from_cam[i]).translation - run.centre_in_enu[i])
              .norm();
      const bool near = i >= 20 && i <= 220;
      (near ? b.near : b.far) = std::max(near ? b.near : b.far, d);
    }
    return b;
  };
  const GeorefTransform held = PiecewiseTransform(anchors(1.0, false));
  // Off by default; followed for 20 m (half the anchors' default window), and for ever.
  EXPECT_FALSE(PiecewiseTransform(anchors(1.0, true)).after_drift.has_value());
  const GeorefTransform drifting = PiecewiseTransform(anchors(1.0, true), 1.0, 20.0);
  const GeorefTransform unbounded = PiecewiseTransform(anchors(1.0, true), 1.0, 1000.0);
  const GeorefTransform off = PiecewiseTransform(anchors(1.0, true), 1.0, 0.0);
  const GeorefTransform other = PiecewiseTransform(anchors(3.0, true), 1.0, 20.0);
  EXPECT_FALSE(held.after_drift.has_value());
  ASSERT_TRUE(drifting.before_drift.has_value());
  ASSERT_TRUE(drifting.after_drift.has_value());
  EXPECT_FALSE(off.after_drift.has_value());
  EXPECT_FALSE(other.after_drift.has_value());
  const Beyond h = beyond(held), d = beyond(drifting), u = beyond(unbounded);
  std::printf(
      "max error within 20 m / 20-40 m beyond the end anchors: the end anchors' scales held "
      "%.3f / %.3f m, their drifts followed for 20 m %.3f / %.3f m, for ever %.3f / %.3f m\n",
      h.near, h.far, d.near, d.far, u.near, u.far);
  // Held, the scale is 3.3 % off 20 m on and the position by about drift' x^2 / 2 = 0.33 m
  // there (1.3 m at 40 m); the drift followed leaves its own change along the way (the drift is
  // the anchor's, 1 / (1 + drift w) bends) and the chord's shortening on the 150 m arc.
  EXPECT_GT(h.near, 0.25);
  EXPECT_LT(d.near, 0.1 * h.near);
  // Beyond the reach the scale reached at 20 m is held: the error grows again, though less
  // than with the end anchor's scale held from the anchor; followed for ever, exact to the
  // drive's ends but for the drift's own bend and the chord.
  EXPECT_LT(d.far, 0.5 * h.far);
  EXPECT_LT(u.far, 0.5 * d.far);
  EXPECT_NEAR(d.near, u.near, 1e-12);
  // Reach 0 (off), and another trajectory's drift (its scales three times these units): the
  // end anchors' scales held, as without drifts.
  EXPECT_NEAR(beyond(off).far, h.far, 1e-12);
  EXPECT_NEAR(beyond(other).far, beyond(PiecewiseTransform(anchors(3.0, false))).far, 1e-12);
  // Exact at the anchors, with the scale there.
  for (const AnchorPair& a : anchors(1.0, true)) {
    double scale = 0.0;
    EXPECT_LT(
        (drifting.Map(a.timestamp_s, a.vo_from_cam, &scale).translation - a.centre_in_enu).norm(),
        1e-9);
  }
  // The scale reported beyond: the end's, changed by the end anchor's drift over the distance.
  const AnchorPair last = anchors(1.0, true).back();
  double scale = 0.0;
  drifting.Map(run.times[210], run.vo_from_cam[210], &scale);
  const double end_scale = drifting.after->scale;
  const double x =
      end_scale * (run.vo_from_cam[210].translation - last.vo_from_cam.translation).norm();
  EXPECT_NEAR(scale, end_scale * (1.0 + *last.scale_drift_per_m * x), 1e-9);
}

// The anchors file's scale_m_per_unit column: a positive number is the anchor's scale; empty,
// not a number, or not positive is none (the row stays an anchor). scale_drift_per_m: any finite
// number is the anchor's drift.
TEST(Georef, ReadsTheAnchorsOwnScales) {
  const TempDir dir;
  ResultTable table;
  table.extra_columns = {"scale_m_per_unit", "scale_drift_per_m"};
  const std::vector<std::string> values = {"1.25", "", "nan", "-2", "abc", "0.5x"};
  for (size_t i = 0; i < values.size(); ++i) {
    ResultRow row;
    row.frame = static_cast<frame_t>(i);
    row.timestamp_s = 10.0 + static_cast<double>(i);
    row.method = "anchor";
    row.status = ResultStatus::kOk;
    row.position = Geodetic{49.0, 8.4 + 1e-5 * static_cast<double>(i), 115.0};
    row.has_position = true;
    row.enu_from_cam = Eigen::Quaterniond::Identity();
    row.extra = {values[i], values[i]};
    table.rows.push_back(row);
  }
  WriteResultCsv(table, dir / "anchors.csv");
  const AnchorSet set = ReadAnchors(dir / "anchors.csv");
  ASSERT_EQ(set.anchors.size(), values.size());
  ASSERT_TRUE(set.anchors[0].scale_m_per_unit.has_value());
  EXPECT_EQ(*set.anchors[0].scale_m_per_unit, 1.25);
  for (size_t i = 1; i < values.size(); ++i) {
    EXPECT_FALSE(set.anchors[i].scale_m_per_unit.has_value()) << values[i];
  }
  EXPECT_EQ(set.anchors[0].scale_drift_per_m, 1.25);
  EXPECT_EQ(set.anchors[3].scale_drift_per_m, -2.0);
  for (const size_t i : {1, 2, 4, 5}) {
    EXPECT_FALSE(set.anchors[i].scale_drift_per_m.has_value()) << values[i];
  }
  // Without the column: no scales.
  table.extra_columns.clear();
  for (ResultRow& row : table.rows) row.extra.clear();
  WriteResultCsv(table, dir / "plain.csv");
  for (const Anchor& a : ReadAnchors(dir / "plain.csv").anchors) {
    EXPECT_FALSE(a.scale_m_per_unit.has_value());
    EXPECT_FALSE(a.scale_drift_per_m.has_value());
  }
}

// The whole path: anchors as geodetic positions with local-ENU orientations, the VO trajectory on
// the drive's clock, rows per requested frame; frames outside the trajectory are lost.
TEST(Georef, GeoreferenceWritesRowsPerFrame) {
  const SyntheticRun run = MakeRun(101, 0.3, 1.0);
  const Geodetic origin{49.01, 8.41, 115.0};
  const EnuFrame enu(origin);
  ImportedTrajectory trajectory;
  trajectory.path = "vo.tum";
  for (size_t i = 0; i < run.times.size(); ++i) {
    StampedPose pose;
    pose.timestamp_s = run.times[i];
    pose.world_from_cam = run.vo_from_cam[i];
    trajectory.poses.push_back(pose);
  }
  AnchorSet anchors;
  anchors.path = "anchors.csv";
  for (size_t i = 5; i < run.times.size(); i += 25) {  // first anchor at frame 5: the ENU origin
    Anchor a;
    a.frame = static_cast<frame_t>(i);
    a.timestamp_s = run.times[i];
    a.position = enu.ToGeodetic(run.centre_in_enu[i]);
    a.enu_from_cam = Eigen::Quaterniond(enu.EnuFromLocalEnu(a.position).transpose() *
                                        run.enu_from_cam[i].toRotationMatrix());
    anchors.anchors.push_back(a);
  }
  std::vector<GeorefFrame> frames;
  for (size_t i = 0; i < run.times.size(); ++i) {
    frames.push_back({static_cast<frame_t>(i), run.times[i]});
  }
  frames.push_back({1000, run.times.back() + 5.0});  // after the trajectory
  GeorefOptions options;
  options.methods = ParseGeorefMethods("all");
  const GeorefResult result = Georeference(trajectory, anchors, frames, options);
  EXPECT_EQ(result.anchors_ok, 4);
  EXPECT_EQ(result.anchors_associated, 4);
  EXPECT_LT((EnuFrame(result.origin).ToEnu(anchors.anchors[0].position)).norm(), 1e-6);
  ASSERT_EQ(result.methods.size(), 3u);
  ASSERT_EQ(result.table.rows.size(), 3 * frames.size());
  const GeorefMethodSummary& piecewise = result.methods[2];
  EXPECT_EQ(piecewise.method, GeorefMethod::kPiecewise);
  EXPECT_EQ(piecewise.anchors_used, 4);
  EXPECT_EQ(piecewise.rows_ok, 101);
  EXPECT_EQ(piecewise.rows_lost, 1);
  EXPECT_LT(piecewise.anchor_max_m, 1e-6);
  EXPECT_GT(result.methods[1].anchor_rms_m, 0.01);  // sim3 cannot follow the drift
  for (const ResultRow& row : result.table.rows) {
    if (row.method != "piecewise") continue;
    if (row.frame == 1000) {
      EXPECT_EQ(row.status, ResultStatus::kLost);
      continue;
    }
    ASSERT_EQ(row.status, ResultStatus::kOk);
    ASSERT_TRUE(row.enu_from_cam.has_value());
    const Eigen::Vector3d error =
        EnuFrame(origin).ToEnu(row.position) - run.centre_in_enu[static_cast<size_t>(row.frame)];
    if ((row.frame - 5) % 25 == 0) {
      EXPECT_LT(error.norm(), 1e-6) << "anchor frame " << row.frame;
      EXPECT_LT(
          AngleDeg(*row.enu_from_cam,
                   anchors.anchors[static_cast<size_t>(row.frame - 5) / 25].enu_from_cam.value()),
          1e-6);
    } else if (row.frame > 5 && row.frame < 80) {
      // Between anchors 25 m apart with the scale drifting by ~7 % over the interval: at most
      // L dk / 8 = 0.23 m mid-interval (measured 0.221 m).
      EXPECT_LT(error.norm(), 0.25) << "frame " << row.frame;
    } else {
      // Extrapolated from the first / last interval, where the scale keeps drifting (up to 20 m
      // beyond the last anchor).
      EXPECT_LT(error.norm(), 1.5) << "frame " << row.frame;
    }
    EXPECT_GT(std::stod(row.extra.at(0)), 0.0);  // scale_m_per_unit
  }
  // Anchors outside the trajectory's time span are not associated.
  AnchorSet late = anchors;
  for (Anchor& a : late.anchors) a.timestamp_s += 8.0;
  ExpectError(
      [&] { Georeference(trajectory, late, frames, options); },
      {"anchors.csv", "1 of 4 ok anchors fall within the trajectory vo.tum", "time offset"});
}

}  // namespace
}  // namespace epiloc
