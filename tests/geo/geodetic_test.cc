#include "epiloc/geo/geodetic.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include "epiloc/core/error.h"
#include "test_util.h"

namespace epiloc {
namespace {

using ::testing::HasSubstr;

// Longitude difference wrapped to [-180, 180], so points across the
// antimeridian compare.
double LonDiffDeg(double a, double b) { return std::remainder(a - b, 360.0); }


TEST(EnuFrame, RoundTripIsLosslessAroundTheGlobe) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> offset_deg(-0.01, 0.01);
  std::uniform_real_distribution<double> offset_m(-100.0, 100.0);
  const Geodetic origins[] = {
      {0.0, 0.0, 0.0},                       // equator, prime meridian
      {49.0114951367, 8.4167324537, 112.8},  // Karlsruhe (KITTI)
      {-33.87, 151.21, 58.0},                // Sydney
      {89.99, 45.0, 2800.0},                 // near the north pole
      {-89.98, -120.0, 2835.0},              // near the south pole
      {12.5, 179.995, 0.0},  // points on both sides of the antimeridian
      {-17.0, -179.999, -30.0},
  };
  for (const Geodetic& origin : origins) {
    SCOPED_TRACE(fmt::format("origin {} {}", origin.lat_deg, origin.lon_deg));
    const EnuFrame frame(origin);
    EXPECT_LT(frame.ToEnu(origin).norm(), 1e-9);
    for (int i = 0; i < 50; ++i) {
      Geodetic p;
      p.lat_deg = std::clamp(origin.lat_deg + offset_deg(rng), -90.0, 90.0);
      p.lon_deg = std::remainder(origin.lon_deg + offset_deg(rng), 360.0);
      p.alt_m = origin.alt_m + offset_m(rng);
      const Eigen::Vector3d enu = frame.ToEnu(p);
      EXPECT_LT(enu.head<2>().norm(),
                2000.0);  // really local, also across the antimeridian
      const Geodetic back = frame.ToGeodetic(enu);
      EXPECT_NEAR(back.lat_deg, p.lat_deg, 1e-9);
      EXPECT_NEAR(LonDiffDeg(back.lon_deg, p.lon_deg), 0.0, 1e-9);
      EXPECT_NEAR(back.alt_m, p.alt_m, 1e-6);
      EXPECT_LE(std::abs(back.lon_deg), 180.0);
    }
  }
}

TEST(EnuFrame, AxesPointEastNorthUp) {
  const Geodetic origin{49.0, 8.4, 100.0};
  const EnuFrame frame(origin);
  const Eigen::Vector3d up = frame.ToEnu({49.0, 8.4, 110.0});
  EXPECT_NEAR(up.x(), 0.0, 1e-9);
  EXPECT_NEAR(up.y(), 0.0, 1e-9);
  EXPECT_NEAR(up.z(), 10.0, 1e-9);
  EXPECT_GT(frame.ToEnu({49.0, 8.401, 100.0}).x(), 70.0);
  EXPECT_GT(frame.ToEnu({49.001, 8.4, 100.0}).y(), 110.0);
  // Across the antimeridian, east stays east.
  const EnuFrame date_line({0.0, 179.9999, 0.0});
  EXPECT_NEAR(date_line.ToEnu({0.0, -179.9999, 0.0}).x(),
              2 * 0.0001 * 111319.49, 0.01);
}

TEST(EnuFrame, MatchesGeodesicDistancesAt49North) {
  // The geodesic (GeographicLib::Geodesic, independent of LocalCartesian) from
  // the origin to a point 0.001 deg north is the meridian arc; at 111 m the
  // tangent-plane coordinate differs from the arc by nanometres (and the point
  // sits ~1 mm below the plane).
  const Geodetic origin{49.0, 8.4, 0.0};
  const EnuFrame frame(origin);
  const GeographicLib::Geodesic& geodesic = GeographicLib::Geodesic::WGS84();

  double north_arc_m = 0.0;
  geodesic.Inverse(49.0, 8.4, 49.001, 8.4, north_arc_m);
  EXPECT_NEAR(north_arc_m, 111.2, 0.05);
  const Eigen::Vector3d north = frame.ToEnu({49.001, 8.4, 0.0});
  EXPECT_NEAR(north.y(), north_arc_m, 1e-3);
  EXPECT_NEAR(north.x(), 0.0, 1e-3);
  EXPECT_NEAR(north.z(), -north_arc_m * north_arc_m / (2 * 6.38e6), 2e-4);

  double east_m = 0.0;
  double azimuth1_deg = 0.0;
  double azimuth2_deg = 0.0;
  geodesic.Inverse(49.0, 8.4, 49.0, 8.401, east_m, azimuth1_deg, azimuth2_deg);
  EXPECT_NEAR(east_m, 73.1, 0.1);
  const Eigen::Vector3d east = frame.ToEnu({49.0, 8.401, 0.0});
  EXPECT_NEAR(east.head<2>().norm(), east_m, 1e-3);
  // The geodesic leaves the origin slightly north of east (a parallel is not a
  // geodesic).
  EXPECT_NEAR(CompassHeadingFromEnuDirection(east.head<2>()), azimuth1_deg,
              1e-3);
}

TEST(Geodetic, ValidityAndCheckMessages) {
  EXPECT_TRUE(IsValidGeodetic({0.0, 0.0, 0.0}));
  EXPECT_TRUE(IsValidGeodetic({90.0, 180.0, -100.0}));
  EXPECT_TRUE(IsValidGeodetic({-90.0, -180.0, 9000.0}));
  EXPECT_FALSE(IsValidGeodetic({90.0001, 0.0, 0.0}));
  EXPECT_FALSE(IsValidGeodetic({0.0, -180.5, 0.0}));
  EXPECT_FALSE(IsValidGeodetic({std::nan(""), 0.0, 0.0}));
  EXPECT_FALSE(
      IsValidGeodetic({0.0, 0.0, std::numeric_limits<double>::infinity()}));

  EXPECT_NO_THROW(CheckGeodetic({49.0, 8.4, 112.0}, "oxts/0000000042.txt"));
  EXPECT_THAT(
      ErrorOf([] {
        CheckGeodetic({123.0, 8.4, 0.0}, "oxts/0000000042.txt");
      }),
      HasSubstr("oxts/0000000042.txt: latitude 123 out of range [-90, 90]"));
  EXPECT_THAT(ErrorOf([] {
                CheckGeodetic({49.0, -181.0, 0.0}, "gnss.csv:3");
              }),
              HasSubstr("gnss.csv:3: longitude -181 out of range [-180, 180]"));
  EXPECT_THAT(ErrorOf([] {
                CheckGeodetic({std::nan(""), 0.0, 0.0}, "here");
              }),
              HasSubstr("here: latitude nan"));
  EXPECT_THAT(ErrorOf([] {
                CheckGeodetic({0.0, 0.0, std::nan("")}, "here");
              }),
              HasSubstr("here: altitude is not finite"));
  EXPECT_THAT(ErrorOf([] {
                EnuFrame frame({91.0, 0.0, 0.0});
              }),
              HasSubstr("ENU origin"));
}

TEST(EnuFrame, CopiesAreIndependent) {
  auto original = std::make_unique<EnuFrame>(Geodetic{49.0, 8.4, 100.0});
  const Geodetic p{49.001, 8.402, 120.0};
  const Eigen::Vector3d expected = original->ToEnu(p);
  EnuFrame copy(*original);
  EnuFrame assigned({0.0, 0.0, 0.0});
  assigned = *original;
  original.reset();
  EXPECT_EQ(copy.ToEnu(p), expected);
  EXPECT_EQ(assigned.ToEnu(p), expected);
  EXPECT_EQ(assigned.origin().lat_deg, 49.0);
}

TEST(EnuFrame, EnuFromLocalEnuRotatesLocalAxes) {
  const EnuFrame frame({49.0, 8.4, 100.0});
  EXPECT_LT(
      (frame.EnuFromLocalEnu({49.0, 8.4, 100.0}) - Eigen::Matrix3d::Identity())
          .norm(),
      1e-12);
  // 1 m steps along the local axes at a point 5 km away, mapped through the
  // geodetic coordinates, match the rotation (to the curvature over 1 m, ~1e-7
  // m).
  for (const Geodetic& at :
       {Geodetic{49.04, 8.45, 130.0}, Geodetic{48.97, 8.33, 90.0}}) {
    const EnuFrame local(at);
    const Eigen::Matrix3d rotation = frame.EnuFromLocalEnu(at);
    EXPECT_LT(
        (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm(),
        1e-12);
    EXPECT_NEAR(rotation.determinant(), 1.0, 1e-12);
    EXPECT_GT((rotation - Eigen::Matrix3d::Identity()).norm(),
              1e-4);  // not the identity here
    for (int axis = 0; axis < 3; ++axis) {
      const Eigen::Vector3d step_in_local = Eigen::Vector3d::Unit(axis);
      const Eigen::Vector3d step_in_frame =
          frame.ToEnu(local.ToGeodetic(step_in_local)) - frame.ToEnu(at);
      EXPECT_LT((rotation * step_in_local - step_in_frame).norm(), 1e-6);
    }
  }
}

TEST(Heading, FromYaw) {
  EXPECT_NEAR(CompassHeadingFromYaw(0.0), 90.0, 1e-12);            // east
  EXPECT_NEAR(CompassHeadingFromYaw(M_PI / 2), 0.0, 1e-12);        // north
  EXPECT_NEAR(CompassHeadingFromYaw(M_PI), 270.0, 1e-12);          // west
  EXPECT_NEAR(CompassHeadingFromYaw(-M_PI), 270.0, 1e-12);         // west
  EXPECT_NEAR(CompassHeadingFromYaw(-M_PI / 2), 180.0, 1e-12);     // south
  EXPECT_NEAR(CompassHeadingFromYaw(M_PI / 4), 45.0, 1e-12);       // north-east
  EXPECT_NEAR(CompassHeadingFromYaw(3 * M_PI / 4), 315.0, 1e-12);  // north-west
  EXPECT_NEAR(CompassHeadingFromYaw(2 * M_PI), 90.0, 1e-12);
}

TEST(Heading, FromEnuDirection) {
  EXPECT_NEAR(CompassHeadingFromEnuDirection({0.0, 1.0}), 0.0, 1e-12);
  EXPECT_NEAR(CompassHeadingFromEnuDirection({1.0, 0.0}), 90.0, 1e-12);
  EXPECT_NEAR(CompassHeadingFromEnuDirection({0.0, -2.0}), 180.0, 1e-12);
  EXPECT_NEAR(CompassHeadingFromEnuDirection({-3.0, 0.0}), 270.0, 1e-12);
  EXPECT_NEAR(CompassHeadingFromEnuDirection({1.0, -1.0}), 135.0, 1e-12);
}

TEST(Heading, AlwaysInZeroTo360) {
  // Just west of north: atan2 gives a tiny negative angle, which must not
  // become 360.
  EXPECT_LT(CompassHeadingFromEnuDirection({-1e-20, 1.0}), 360.0);
  EXPECT_GE(CompassHeadingFromEnuDirection({-1e-20, 1.0}), 0.0);
  EXPECT_LT(CompassHeadingFromYaw(M_PI / 2 + 1e-17), 360.0);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> yaw(-10.0, 10.0);
  for (int i = 0; i < 1000; ++i) {
    const double heading = CompassHeadingFromYaw(yaw(rng));
    EXPECT_GE(heading, 0.0);
    EXPECT_LT(heading, 360.0);
  }
}

}  // namespace
}  // namespace epiloc
