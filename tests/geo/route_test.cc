#include "epiloc/geo/route.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// East 100 m, then north 50 m while climbing 10 m.
Route LRoute() { return Route({{0, 0, 0}, {100, 0, 0}, {100, 50, 10}}); }

void ExpectVectorNear(const Eigen::Vector3d& actual,
                      const Eigen::Vector3d& expected) {
  EXPECT_LT((actual - expected).norm(), 1e-9)
      << actual.transpose() << " vs " << expected.transpose();
}

TEST(Route, LengthAndCumulativeDistance) {
  const Route route = LRoute();
  EXPECT_DOUBLE_EQ(route.length_m(),
                   150.0);  // horizontal length; the climb does not count
  ASSERT_EQ(route.points().size(), 3u);
  EXPECT_THAT(route.cumulative_s(), ::testing::ElementsAre(0.0, 100.0, 150.0));
}

TEST(Route, ProjectionOnTheFirstLeg) {
  const Route route = LRoute();
  RouteProjection p = route.Project({50, 5, 1});
  EXPECT_NEAR(p.s_m, 50.0, 1e-12);
  EXPECT_NEAR(p.cross_track_m, 5.0, 1e-12);  // north of eastward travel: left
  EXPECT_NEAR(p.vertical_m, 1.0, 1e-12);
  EXPECT_EQ(p.segment, 0);
  EXPECT_TRUE(p.within);
  p = route.Project({20, -3, 0});
  EXPECT_NEAR(p.s_m, 20.0, 1e-12);
  EXPECT_NEAR(p.cross_track_m, -3.0, 1e-12);  // right
}

TEST(Route, ProjectionOnTheSecondLeg) {
  const Route route = LRoute();
  RouteProjection p = route.Project({95, 25, 5});
  EXPECT_NEAR(p.s_m, 125.0, 1e-12);
  EXPECT_NEAR(p.cross_track_m, 5.0, 1e-12);  // west of northward travel: left
  EXPECT_NEAR(p.vertical_m, 0.0, 1e-12);     // the route is at 5 m there
  EXPECT_EQ(p.segment, 1);
  EXPECT_TRUE(p.within);
  p = route.Project({104, 40, 0});
  EXPECT_NEAR(p.s_m, 140.0, 1e-12);
  EXPECT_NEAR(p.cross_track_m, -4.0, 1e-12);
  EXPECT_NEAR(p.vertical_m, -8.0, 1e-12);
}

TEST(Route, BeyondTheEnds) {
  const Route route = LRoute();
  RouteProjection p = route.Project({-10, 2, 0});
  EXPECT_NEAR(p.s_m, -10.0, 1e-12);
  EXPECT_NEAR(p.cross_track_m, 2.0, 1e-12);
  EXPECT_EQ(p.segment, 0);
  EXPECT_FALSE(p.within);
  p = route.Project({99, 70, 10});
  EXPECT_NEAR(p.s_m, 170.0, 1e-12);
  EXPECT_GT(p.s_m, route.length_m());
  EXPECT_NEAR(p.cross_track_m, 1.0, 1e-12);
  EXPECT_EQ(p.segment, 1);
  EXPECT_FALSE(p.within);
  // The ends themselves are within.
  EXPECT_TRUE(route.Project({0, 0, 0}).within);
  EXPECT_TRUE(route.Project({100, 50, 10}).within);
}

TEST(Route, ConsecutiveDuplicatesAreMerged) {
  const Route route({{0, 0, 0},
                     {0, 0, 0},
                     {0.005, 0, 0},
                     {10, 0, 0},
                     {10, 0.001, 0},
                     {10, 5, 0}});
  ASSERT_EQ(route.points().size(), 3u);
  EXPECT_DOUBLE_EQ(route.length_m(), 15.0);
  ExpectVectorNear(route.points()[1], {10, 0, 0});
  // A larger spacing merges more.
  EXPECT_EQ(Route({{0, 0, 0}, {0.5, 0, 0}, {2, 0, 0}}, 1.0).points().size(),
            2u);
  // Points stacked vertically are one horizontal position.
  EXPECT_EQ(Route({{0, 0, 0}, {0, 0, 5}, {3, 0, 0}}).points().size(), 2u);
}

TEST(Route, NeedsTwoDistinctPoints) {
  EXPECT_THROW(Route({}), Error);
  EXPECT_THROW(Route({{1, 1, 1}}), Error);
  EXPECT_THROW(Route({{1, 1, 1}, {1, 1, 1}, {1.001, 1, 2}}), Error);
  EXPECT_THROW(Route({{0, 0, 0}, {std::nan(""), 0, 0}}), Error);
}

TEST(Route, PointAtAndDirectionAt) {
  const Route route = LRoute();
  ExpectVectorNear(route.PointAt(0.0), {0, 0, 0});
  ExpectVectorNear(route.PointAt(50.0), {50, 0, 0});
  ExpectVectorNear(route.PointAt(100.0), {100, 0, 0});
  ExpectVectorNear(route.PointAt(125.0), {100, 25, 5});
  ExpectVectorNear(route.PointAt(150.0), {100, 50, 10});
  ExpectVectorNear(route.PointAt(-10.0),
                   {-10, 0, 0});  // extrapolated backwards
  ExpectVectorNear(route.PointAt(160.0), {100, 60, 12});  // and forwards
  ExpectVectorNear(route.DirectionAt(50.0), {1, 0, 0});
  ExpectVectorNear(route.DirectionAt(-5.0), {1, 0, 0});
  ExpectVectorNear(route.DirectionAt(125.0),
                   {0, 1, 0});  // horizontal, despite the climb
  ExpectVectorNear(route.DirectionAt(500.0), {0, 1, 0});
}

TEST(Route, ProjectAndPointAtAgree) {
  // A random walk: the foot point of a projection is PointAt(s), and the offset
  // is the cross-track distance to the left of DirectionAt(s).
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> step(-10.0, 10.0);
  std::vector<Eigen::Vector3d> points = {{0, 0, 0}};
  for (int i = 0; i < 30; ++i) {
    points.push_back(points.back() + Eigen::Vector3d(20.0 + step(rng),
                                                     step(rng),
                                                     0.1 * step(rng)));
  }
  const Route route(points);
  std::uniform_int_distribution<int> segment(
      0, static_cast<int>(route.points().size()) - 2);
  std::uniform_real_distribution<double> fraction(0.0, 1.0);
  std::uniform_real_distribution<double> offset(-1.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    // At least 2 m from a vertex, so no other segment is nearer than the 1 m
    // offset (turns are below 90 degrees).
    const int k = segment(rng);
    const double begin = route.cumulative_s()[k] + 2.0;
    const double end = route.cumulative_s()[k + 1] - 2.0;
    const double s = begin + fraction(rng) * (end - begin);
    const Eigen::Vector3d direction = route.DirectionAt(s);
    const Eigen::Vector3d left(-direction.y(), direction.x(), 0.0);
    const double cross = offset(rng);
    const Eigen::Vector3d p =
        route.PointAt(s) + cross * left + Eigen::Vector3d(0, 0, 2.0);
    const RouteProjection projection = route.ProjectNear(p, s, 5.0);
    EXPECT_NEAR(projection.s_m, s, 1e-9);
    EXPECT_NEAR(projection.cross_track_m, cross, 1e-9);
    EXPECT_NEAR(projection.vertical_m, 2.0, 1e-9);
    EXPECT_TRUE(projection.within);
  }
}

TEST(Route, ProjectNearPicksThePassNearTheHint) {
  // Out along y = 0 and back along y = 2: the point (30, 1) is on both passes.
  const Route route({{0, 0, 0}, {100, 0, 0}, {100, 2, 0}, {0, 2, 0}});
  ASSERT_DOUBLE_EQ(route.length_m(), 202.0);
  const Eigen::Vector3d p(30, 1, 0);

  const RouteProjection out = route.ProjectNear(p, 35.0, 20.0);
  EXPECT_NEAR(out.s_m, 30.0, 1e-12);
  EXPECT_NEAR(out.cross_track_m, 1.0, 1e-12);  // north of eastward travel
  EXPECT_EQ(out.segment, 0);

  const RouteProjection back = route.ProjectNear(p, 165.0, 20.0);
  EXPECT_NEAR(back.s_m, 172.0, 1e-12);
  EXPECT_NEAR(back.cross_track_m, 1.0, 1e-12);  // south of westward travel
  EXPECT_EQ(back.segment, 2);

  // A global projection finds one of the two, at the same distance.
  const RouteProjection any = route.Project(p);
  EXPECT_TRUE(std::abs(any.s_m - 30.0) < 1e-9 ||
              std::abs(any.s_m - 172.0) < 1e-9);
  EXPECT_NEAR(std::abs(any.cross_track_m), 1.0, 1e-12);
}

}  // namespace
}  // namespace epiloc
