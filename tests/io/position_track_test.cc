#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"
#include "io_test_util.h"

namespace epiloc {
namespace {

const Geodetic kOrigin{49.0, 8.4, 100.0};

Eigen::Quaterniond Yaw(double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
}

PositionSample Sample(double t, const Eigen::Vector3d& enu, std::optional<double> yaw_deg) {
  PositionSample s;
  s.timestamp_s = t;
  s.position = EnuFrame(kOrigin).ToGeodetic(enu);
  if (yaw_deg) s.enu_from_cam = Yaw(*yaw_deg);
  s.frame = static_cast<frame_t>(t * 10);
  return s;
}

Eigen::Vector3d Enu(const PositionSample& s) { return EnuFrame(kOrigin).ToEnu(s.position); }

PositionTrack ThreeSamples() {
  PositionTrack track;
  track.samples = {Sample(0, {0, 0, 0}, 0.0), Sample(1, {10, 0, 0}, 90.0),
                   Sample(2, {10, 20, 2}, 90.0)};
  return track;
}

TEST(Interpolate, LinearAtMidpointsWithSlerp) {
  const PositionTrack track = ThreeSamples();
  const auto a = track.Interpolate(0.5, 0.6);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->timestamp_s, 0.5);
  EXPECT_EQ(a->frame, kInvalidFrame);
  EXPECT_LT((Enu(*a) - Eigen::Vector3d(5, 0, 0)).norm(), 1e-6);
  ASSERT_TRUE(a->enu_from_cam.has_value());
  // ENU axes at 5 m east of the origin turn by ~5/6.4e6 rad about north: far below 1e-3 deg.
  EXPECT_LT(RotationDifferenceDeg(*a->enu_from_cam, Yaw(45)), 1e-3);

  const auto b = track.Interpolate(1.5, 0.6);
  ASSERT_TRUE(b.has_value());
  EXPECT_LT((Enu(*b) - Eigen::Vector3d(10, 10, 1)).norm(), 1e-4);
  EXPECT_LT(RotationDifferenceDeg(*b->enu_from_cam, Yaw(90)), 1e-3);

  const auto quarter = track.Interpolate(0.25, 0.8);
  ASSERT_TRUE(quarter.has_value());
  EXPECT_LT((Enu(*quarter) - Eigen::Vector3d(2.5, 0, 0)).norm(), 1e-6);
  EXPECT_LT(RotationDifferenceDeg(*quarter->enu_from_cam, Yaw(22.5)), 1e-3);
}

TEST(Interpolate, ExactSampleTimeReturnsTheSample) {
  const PositionTrack track = ThreeSamples();
  const auto s = track.Interpolate(1.0, 0.1);
  ASSERT_TRUE(s.has_value());
  EXPECT_TRUE(*s == track.samples[1]);
  EXPECT_EQ(s->frame, 10);
}

TEST(Interpolate, MaxGapLeavesHoles) {
  PositionTrack track;
  track.samples = {Sample(0, {0, 0, 0}, std::nullopt), Sample(1, {10, 0, 0}, std::nullopt),
                   Sample(5, {50, 0, 0}, std::nullopt), Sample(6, {60, 0, 0}, std::nullopt)};
  EXPECT_TRUE(track.Interpolate(0.5, 0.6).has_value());
  EXPECT_FALSE(track.Interpolate(0.5, 0.4).has_value());  // both neighbours 0.5 s away
  EXPECT_FALSE(track.Interpolate(1.5, 0.6).has_value());  // next sample 3.5 s away
  EXPECT_FALSE(track.Interpolate(3.0, 0.6).has_value());
  EXPECT_FALSE(track.Interpolate(4.5, 0.6).has_value());  // previous sample 3.5 s away
  EXPECT_TRUE(track.Interpolate(5.5, 0.6).has_value());
  EXPECT_FALSE(track.Interpolate(0.5, 0.6)->enu_from_cam.has_value());
}

TEST(Interpolate, ExtrapolatesTheEndsWithinTheGap) {
  const PositionTrack track = ThreeSamples();
  const auto before = track.Interpolate(-0.3, 0.5);
  ASSERT_TRUE(before.has_value());
  EXPECT_LT((Enu(*before) - Eigen::Vector3d(-3, 0, 0)).norm(), 1e-6);
  EXPECT_LT(RotationDifferenceDeg(*before->enu_from_cam, Yaw(-27)), 1e-3);
  EXPECT_FALSE(track.Interpolate(-0.6, 0.5).has_value());
  const auto after = track.Interpolate(2.4, 0.5);
  ASSERT_TRUE(after.has_value());
  EXPECT_LT((Enu(*after) - Eigen::Vector3d(10, 28, 2.8)).norm(), 1e-4);
  EXPECT_FALSE(track.Interpolate(2.6, 0.5).has_value());
}

TEST(Interpolate, SingleSampleAndEmpty) {
  PositionTrack track;
  EXPECT_FALSE(track.Interpolate(0, 1).has_value());
  track.samples = {Sample(1, {3, 4, 5}, 30.0)};
  const auto s = track.Interpolate(1.2, 0.5);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->timestamp_s, 1.2);
  EXPECT_LT((Enu(*s) - Eigen::Vector3d(3, 4, 5)).norm(), 1e-8);
  EXPECT_FALSE(track.Interpolate(1.6, 0.5).has_value());
}

TEST(PositionFrames, ReportsFramesWithoutPosition) {
  Drive drive;
  drive.name = "test";
  drive.max_gap_s = 0.6;
  for (int i = 0; i <= 12; ++i) drive.frames.push_back({100 + i, i * 0.5, ""});
  PositionTrack track;
  track.source = "gnss.csv";
  track.samples = {Sample(0, {0, 0, 0}, std::nullopt), Sample(1, {10, 0, 0}, std::nullopt),
                   Sample(5, {50, 0, 0}, std::nullopt), Sample(6, {60, 0, 0}, std::nullopt)};
  const FramePositions result = PositionFrames(drive, track);
  ASSERT_EQ(result.per_frame.size(), drive.frames.size());
  // 1.5 s and 4.5 s are only 0.5 s from a sample but lie in the gap between 1 and 5 s, where the
  // sample on the other side is too far.
  const std::vector<frame_t> expected_missing = {103, 104, 105, 106, 107, 108, 109};
  EXPECT_EQ(result.missing, expected_missing);
  ASSERT_TRUE(result.per_frame[1].has_value());
  EXPECT_EQ(result.per_frame[1]->frame, 101);
  EXPECT_LT((Enu(*result.per_frame[1]) - Eigen::Vector3d(5, 0, 0)).norm(), 1e-6);
  EXPECT_FALSE(result.per_frame[4].has_value());
  EXPECT_TRUE(result.per_frame[12].has_value());
}

}  // namespace
}  // namespace epiloc
