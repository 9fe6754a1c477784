#include "epiloc/anchor/pose_prior.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "epiloc/anchor/anchor.h"
#include "test_util.h"

namespace epiloc {
namespace {

const Geodetic kOrigin{49.0, 8.4, 100.0};

TEST(PosePrior, CameraRotationConventions) {
  // Heading 90 (east): optical axis east, x right = south, y down.
  const Eigen::Matrix3d r = MapFromCamRotation(90.0);
  EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_TRUE(r.col(0).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));
  EXPECT_TRUE(r.col(1).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  EXPECT_NEAR(CameraHeadingDeg(r), 90.0, 1e-9);
  // Pitched up 10 degrees: the optical axis rises.
  const Eigen::Matrix3d up = MapFromCamRotation(0.0, 10.0, 0.0);
  EXPECT_NEAR(up.col(2).z(), std::sin(10.0 * M_PI / 180.0), 1e-12);
  EXPECT_NEAR(CameraHeadingDeg(up), 0.0, 1e-9);
  // Rolled: the x axis tilts, the heading does not change.
  const Eigen::Matrix3d rolled = MapFromCamRotation(200.0, 0.0, 5.0);
  EXPECT_NEAR(std::abs(rolled.col(0).z()), std::sin(5.0 * M_PI / 180.0), 1e-12);
  EXPECT_NEAR(CameraHeadingDeg(rolled), 200.0, 1e-9);
}

// GNSS samples at 10 Hz along a circle of radius 50 m driven counter-clockwise at 5 m/s, with
// white noise of `sigma_m`.
PositionTrack CircleTrack(double sigma_m, uint64_t seed) {
  const EnuFrame enu(kOrigin);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_m);
  PositionTrack track;
  for (int i = 0; i <= 300; ++i) {
    const double t = 0.1 * i;
    const double angle = 5.0 * t / 50.0;
    const Eigen::Vector3d p(50.0 * std::cos(angle) + noise(rng),
                            50.0 * std::sin(angle) + noise(rng), 0.0);
    PositionSample s;
    s.timestamp_s = t;
    s.position = enu.ToGeodetic(p);
    track.samples.push_back(s);
  }
  return track;
}

TEST(PosePrior, TrackHeadingFollowsACurve) {
  const EnuFrame enu(kOrigin);
  const PositionTrack track = CircleTrack(0.0, 1);
  const PriorOptions options;
  for (const double t : {5.0, 12.3, 20.0}) {
    // Tangent of a counter-clockwise circle at angle a: direction a + 90 deg (ENU), compass
    // heading 90 - (a + 90) = -a.
    const double a = 5.0 * t / 50.0 * 180.0 / M_PI;
    const double expected = std::fmod(360.0 - a, 360.0);
    const auto heading = TrackHeadingDeg(track, enu, t, options);
    ASSERT_TRUE(heading.has_value());
    EXPECT_NEAR(*heading, expected, 0.05) << "t = " << t;
  }
  // With 1 m white noise the fit still gives the heading to a few degrees.
  const PositionTrack noisy = CircleTrack(1.0, 2);
  const auto heading = TrackHeadingDeg(noisy, enu, 12.3, options);
  ASSERT_TRUE(heading.has_value());
  EXPECT_NEAR(*heading, 360.0 - 5.0 * 12.3 / 50.0 * 180.0 / M_PI, 3.0);
}

TEST(PosePrior, NoTrackHeadingWhileStandingStill) {
  const EnuFrame enu(kOrigin);
  PositionTrack track;
  for (int i = 0; i < 50; ++i) {
    PositionSample s;
    s.timestamp_s = 0.1 * i;
    s.position = kOrigin;
    track.samples.push_back(s);
  }
  EXPECT_FALSE(TrackHeadingDeg(track, enu, 2.0, PriorOptions()).has_value());
}

TEST(PosePrior, GroundHeightIsALowPercentileOfNearbyPoints) {
  PointCloud cloud;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> xy(-3.0, 3.0);
  for (int i = 0; i < 500; ++i) {  // road at z = 2
    cloud.positions.emplace_back(xy(rng), xy(rng), 2.0f);
  }
  for (int i = 0; i < 200; ++i) {  // a car on it, up to 1.5 m high
    cloud.positions.emplace_back(1.0f, 1.0f, static_cast<float>(2.0 + 1.5 * i / 200.0));
  }
  cloud.positions.emplace_back(0.0f, 0.0f, -5.0f);  // one stray point below the road
  const PriorOptions options;
  const auto ground = GroundHeight(cloud, Eigen::Vector2d(0, 0), options);
  ASSERT_TRUE(ground.has_value());
  EXPECT_NEAR(*ground, 2.0, 1e-6);
  EXPECT_FALSE(GroundHeight(cloud, Eigen::Vector2d(100, 100), options).has_value());
}

PosePrior TestPrior() {
  PosePrior prior;
  prior.frame = 7;
  prior.heading_deg = 30.0;
  prior.position_in_map = Eigen::Vector3d(10, 20, 1.65);
  prior.map_from_cam = Rigid3d::FromMatrix(MapFromCamRotation(30.0), prior.position_in_map);
  return prior;
}

TEST(PosePrior, CandidatesStartWithThePriorAndAStencil) {
  const PosePrior prior = TestPrior();
  CandidateOptions options;
  options.num_candidates = 9;
  const std::vector<Rigid3d> c = GenerateCandidates(prior, options, 5);
  ASSERT_EQ(c.size(), 9u);
  EXPECT_TRUE(c[0].translation.isApprox(prior.position_in_map));
  EXPECT_NEAR(CameraHeadingDeg(c[1].rotation.toRotationMatrix()), 30.0 + options.yaw_range_deg,
              1e-9);
  EXPECT_NEAR(CameraHeadingDeg(c[2].rotation.toRotationMatrix()), 30.0 - options.yaw_range_deg,
              1e-9);
  const Eigen::Vector3d forward(std::sin(M_PI / 6), std::cos(M_PI / 6), 0.0);
  EXPECT_TRUE((c[3].translation - prior.position_in_map)
                  .isApprox(options.along_range_m * forward, 1e-9));
  const Eigen::Vector3d right(std::cos(M_PI / 6), -std::sin(M_PI / 6), 0.0);
  EXPECT_TRUE((c[6].translation - prior.position_in_map)
                  .isApprox(-options.lateral_range_m * right, 1e-9));
  // The random rest stays within the ranges and depends on the seed only.
  for (size_t i = 7; i < c.size(); ++i) {
    const Eigen::Vector3d d = c[i].translation - prior.position_in_map;
    EXPECT_LE(std::abs(d.dot(forward)), options.along_range_m + 1e-9);
    EXPECT_LE(std::abs(d.dot(right)), options.lateral_range_m + 1e-9);
    EXPECT_LE(std::abs(d.z()), options.height_range_m + 1e-9);
  }
  const std::vector<Rigid3d> again = GenerateCandidates(prior, options, 5);
  const std::vector<Rigid3d> other = GenerateCandidates(prior, options, 6);
  EXPECT_TRUE(again[8].translation.isApprox(c[8].translation));
  EXPECT_FALSE(other[8].translation.isApprox(c[8].translation));
  options.num_candidates = 0;
  ExpectError([&] { GenerateCandidates(prior, options, 1); }, {"--candidates"});
}

TEST(PosePrior, RotatePriorHeadingKeepsThePosition) {
  const PosePrior rotated = RotatePriorHeading(TestPrior(), -40.0);
  EXPECT_NEAR(rotated.heading_deg, 350.0, 1e-9);
  EXPECT_NEAR(CameraHeadingDeg(rotated.map_from_cam.rotation.toRotationMatrix()), 350.0, 1e-9);
  EXPECT_TRUE(rotated.map_from_cam.translation.isApprox(TestPrior().position_in_map));
}

}  // namespace
}  // namespace epiloc
