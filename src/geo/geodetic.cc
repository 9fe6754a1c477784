#include "epiloc/geo/geodetic.h"

#include <cmath>
#include <vector>

#include <GeographicLib/LocalCartesian.hpp>

#include "epiloc/core/error.h"

namespace epiloc {

bool IsValidGeodetic(const Geodetic& p) {
  return std::isfinite(p.lat_deg) && std::isfinite(p.lon_deg) && std::isfinite(p.alt_m) &&
         std::abs(p.lat_deg) <= 90.0 && std::abs(p.lon_deg) <= 180.0;
}

void CheckGeodetic(const Geodetic& p, const std::string& where) {
  if (!std::isfinite(p.lat_deg) || std::abs(p.lat_deg) > 90.0) {
    Throw("{}: latitude {} out of range [-90, 90]", where, p.lat_deg);
  }
  if (!std::isfinite(p.lon_deg) || std::abs(p.lon_deg) > 180.0) {
    Throw("{}: longitude {} out of range [-180, 180]", where, p.lon_deg);
  }
  if (!std::isfinite(p.alt_m)) Throw("{}: altitude is not finite", where);
  if (p.alt_m < kMinAltitudeM || p.alt_m > kMaxAltitudeM) {
    Throw("{}: altitude {} m out of range [{}, {}]", where, p.alt_m, kMinAltitudeM,
          kMaxAltitudeM);
  }
}

EnuFrame::EnuFrame(const Geodetic& origin)
    : origin_(origin),
      local_(std::make_unique<GeographicLib::LocalCartesian>(origin.lat_deg, origin.lon_deg,
                                                             origin.alt_m)) {
  CheckGeodetic(origin, "ENU origin");
}

EnuFrame::~EnuFrame() = default;

EnuFrame::EnuFrame(const EnuFrame& other)
    : origin_(other.origin_),
      local_(std::make_unique<GeographicLib::LocalCartesian>(*other.local_)) {}

EnuFrame& EnuFrame::operator=(const EnuFrame& other) {
  if (this != &other) {
    origin_ = other.origin_;
    local_ = std::make_unique<GeographicLib::LocalCartesian>(*other.local_);
  }
  return *this;
}

Eigen::Vector3d EnuFrame::ToEnu(const Geodetic& p) const {
  Eigen::Vector3d enu;
  local_->Forward(p.lat_deg, p.lon_deg, p.alt_m, enu.x(), enu.y(), enu.z());
  return enu;
}

Geodetic EnuFrame::ToGeodetic(const Eigen::Vector3d& enu) const {
  Geodetic p;
  local_->Reverse(enu.x(), enu.y(), enu.z(), p.lat_deg, p.lon_deg, p.alt_m);
  return p;
}

Eigen::Matrix3d EnuFrame::EnuFromLocalEnu(const Geodetic& at) const {
  std::vector<double> m(9);
  double x, y, z;
  local_->Forward(at.lat_deg, at.lon_deg, at.alt_m, x, y, z, m);
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(m.data());
}

double CompassHeadingFromEnuDirection(const Eigen::Vector2d& direction_en) {
  double heading = std::atan2(direction_en.x(), direction_en.y()) * 180.0 / M_PI;
  if (heading < 0) heading += 360.0;
  // Just west of north, a tiny negative angle rounds to 360; keep [0, 360).
  if (heading >= 360.0) heading = 0.0;
  return heading;
}

double CompassHeadingFromYaw(double yaw_rad) {
  return CompassHeadingFromEnuDirection(Eigen::Vector2d(std::cos(yaw_rad), std::sin(yaw_rad)));
}

}  // namespace epiloc
