// ScaleTrendOfAnchors (anchor/structure_anchor.h): the VO's scale trend from the ok anchors.
#include <cmath>
#include <optional>
#include <utility>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "epiloc/anchor/structure_anchor.h"

namespace epiloc {
namespace {

// An ok anchor of `frame` with its camera at `centre` (map) and the VO's scale there.
AnchorResult OkAnchor(frame_t frame, const Eigen::Vector3d& centre, double scale_m_per_unit) {
  AnchorResult a;
  a.frame = frame;
  a.status = AnchorStatus::kOk;
  a.has_pose = true;
  a.map_from_cam.translation = centre;
  a.scale_m_per_unit = scale_m_per_unit;
  return a;
}

// The VO's scale trend from the anchors: ok anchors 10 m apart on an L-shaped path (the distance
// is the travelled one, not the straight line), scales exp(-0.002 x): -20 % per 100 m exactly.
// Rejected anchors, even with wild scales, and frames without a pose do not count; fewer than
// three ok anchors, or less than 10 m between the first and the last, give none.
TEST(StructureAnchorTrend, ScaleTrendOfAnchorsIsTheSlopeOfLogScaleOverTheDistanceTravelled) {
  AnchorDriveResult result;
  for (int i = 0; i < 8; ++i) {
    const double x = 10.0 * i;  // 40 m east, then 30 m north
    result.frames.push_back(OkAnchor(
        10 * i, i <= 4 ? Eigen::Vector3d(x, 0.0, 2.0) : Eigen::Vector3d(40.0, x - 40.0, 2.0),
        1.4 * std::exp(-0.002 * x)));
  }
  result.frames[2].status = AnchorStatus::kRejected;
  result.frames[2].scale_m_per_unit = 9.0;
  AnchorResult lost;
  lost.frame = 75;
  lost.status = AnchorStatus::kLost;
  result.frames.push_back(lost);
  // Out of frame order in the result: the trend sorts by frame.
  std::swap(result.frames[3], result.frames[6]);

  const std::optional<VoScaleTrend> trend = ScaleTrendOfAnchors(result);
  ASSERT_TRUE(trend.has_value());
  EXPECT_EQ(trend->anchors, 7);
  EXPECT_NEAR(trend->distance_m, 70.0, 1e-9);
  EXPECT_NEAR(trend->percent_per_100m, -20.0, 1e-9);
  EXPECT_NEAR(trend->first_scale, 1.4, 1e-9);
  EXPECT_NEAR(trend->last_scale, 1.4 * std::exp(-0.14), 1e-9);

  AnchorDriveResult two;
  two.frames = {result.frames[0], result.frames[1]};
  EXPECT_FALSE(ScaleTrendOfAnchors(two).has_value());
  AnchorDriveResult short_run;
  for (int i = 0; i < 4; ++i) {
    AnchorResult a = result.frames[0];
    a.frame = i;
    a.map_from_cam.translation.x() = 3.0 * i;  // 9 m in all
    short_run.frames.push_back(a);
  }
  EXPECT_FALSE(ScaleTrendOfAnchors(short_run).has_value());
}

// A VO restarted after a tracking loss (frame 40) starts its second segment with another scale
// (x 0.6 here); within each the scale falls by 20 % per 100 m. Fitted as one line the jump
// reads as a steep trend; with the segments each keeps its own level and the slope is exact. A
// third segment with a single ok anchor says nothing about the slope and is left out.
TEST(StructureAnchorTrend, EachVoSegmentKeepsItsOwnScale) {
  AnchorDriveResult result;
  for (int i = 0; i < 9; ++i) {
    const double x = 10.0 * i;
    result.frames.push_back(OkAnchor(10 * i, Eigen::Vector3d(x, 0.0, 2.0),
                                     (i < 4   ? 1.4
                                      : i < 8 ? 0.84
                                              : 3.0) *
                                         std::exp(-0.002 * x)));
  }
  const auto segment_of = [](frame_t f) { return f < 40 ? 0 : f < 80 ? 1 : 2; };
  AnchorDriveResult two_segments = result;
  two_segments.frames.pop_back();
  const std::optional<VoScaleTrend> plain = ScaleTrendOfAnchors(two_segments);
  ASSERT_TRUE(plain.has_value());
  const std::optional<VoScaleTrend> trend = ScaleTrendOfAnchors(result, segment_of);
  ASSERT_TRUE(trend.has_value());
  EXPECT_NEAR(trend->percent_per_100m, -20.0, 1e-9);
  EXPECT_GT(std::abs(plain->percent_per_100m + 20.0), 10.0);
  EXPECT_EQ(trend->anchors, 8);
  EXPECT_EQ(trend->segments, 2);
  EXPECT_NEAR(trend->distance_m, 60.0, 1e-9);  // 0-30 m and 40-70 m
  EXPECT_NEAR(trend->first_scale, 1.4, 1e-9);
  EXPECT_NEAR(trend->last_scale, 0.84 * std::exp(-0.14), 1e-9);  // the last one fitted
  EXPECT_NEAR(ScaleTrendOfAnchors(two_segments, segment_of)->percent_per_100m, -20.0, 1e-9);
  // Every segment a single anchor: no trend.
  EXPECT_FALSE(ScaleTrendOfAnchors(result, [](frame_t f) { return static_cast<int>(f); }));
}

}  // namespace
}  // namespace epiloc
