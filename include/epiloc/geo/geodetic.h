// WGS-84 positions and the local east-north-up (ENU) frame of a route database.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace GeographicLib {
class LocalCartesian;
}

namespace epiloc {

// A WGS-84 position: latitude and longitude in degrees, altitude in metres above the ellipsoid
// (KITTI OXTS and NMEA altitudes are used as given; only differences matter within a database).
struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double alt_m = 0.0;
};

// True if lat is in [-90, 90], lon in [-180, 180] and all three are finite.
bool IsValidGeodetic(const Geodetic& position);
// Ellipsoidal heights a road position can have, metres (the Dead Sea shore is at about -400 m,
// the highest roads below 6000 m); outside them a value is an error in the data.
constexpr double kMinAltitudeM = -1000.0;
constexpr double kMaxAltitudeM = 20000.0;
// Throws Error "<where>: latitude 123 out of range [-90, 90]" (or the longitude, or an altitude
// outside [kMinAltitudeM, kMaxAltitudeM]) if invalid.
void CheckGeodetic(const Geodetic& position, const std::string& where);

// A local tangent-plane frame: x east, y north, z up, metres, origin at `origin`.
// Exact (geocentric, via GeographicLib::LocalCartesian), so round trips are lossless to < 1 nm.
class EnuFrame {
 public:
  explicit EnuFrame(const Geodetic& origin);
  ~EnuFrame();
  EnuFrame(const EnuFrame& other);
  EnuFrame& operator=(const EnuFrame& other);

  const Geodetic& origin() const { return origin_; }
  Eigen::Vector3d ToEnu(const Geodetic& position) const;
  Geodetic ToGeodetic(const Eigen::Vector3d& point_in_enu) const;
  // Rotation taking vectors in the local ENU frame at `at` into this frame (v_this = R * v_local);
  // identity at the origin, differs by the meridian convergence and curvature elsewhere.
  Eigen::Matrix3d EnuFromLocalEnu(const Geodetic& at) const;

 private:
  Geodetic origin_;
  std::unique_ptr<GeographicLib::LocalCartesian> local_;
};

// Heading conventions. Compass heading: degrees clockwise from north in [0, 360).
// ENU yaw: radians counter-clockwise from east (KITTI OXTS convention).
double CompassHeadingFromEnuDirection(const Eigen::Vector2d& direction_en);
double CompassHeadingFromYaw(double yaw_rad);

}  // namespace epiloc
