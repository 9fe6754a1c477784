#include "epiloc/camera/camera.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/error.h"

namespace epiloc {

bool Camera::HasDistortion() const {
  for (const double d : distortion) {
    if (d != 0.0) return true;
  }
  return false;
}

Eigen::Matrix3d Camera::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

void Camera::Check(const std::string& where) const {
  if (width <= 0 || height <= 0) Throw("{}: image size {}x{} must be positive", where, width, height);
  if (width >= kMaxImageSide || height >= kMaxImageSide) {
    Throw("{}: image size {}x{} is not below {} pixels a side", where, width, height,
          kMaxImageSide);
  }
  if (!(std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0)) {
    Throw("{}: focal lengths fx={} fy={} must be positive", where, fx, fy);
  }
  // A pinhole focal length outside these bounds is a field of view above ~175 deg or below
  // ~0.3 deg: a typo or a unit mistake, never a road camera.
  const double side = std::max(width, height);
  for (const double f : {fx, fy}) {
    if (f < kMinFocalPerSide * side || f > kMaxFocalPerSide * side) {
      Throw("{}: focal length {} px is outside the sane range [{}, {}] px for a {}x{} image",
            where, f, kMinFocalPerSide * side, kMaxFocalPerSide * side, width, height);
    }
  }
  if (!(std::isfinite(cx) && std::isfinite(cy))) Throw("{}: principal point is not finite", where);
  if (cx < 0 || cy < 0 || cx > width || cy > height) {
    Throw("{}: principal point ({}, {}) lies outside the {}x{} image", where, cx, cy, width,
          height);
  }
  for (const double d : distortion) {
    if (!std::isfinite(d)) Throw("{}: distortion coefficient is not finite", where);
  }
  static const char* const kNames[5] = {"k1", "k2", "p1", "p2", "k3"};
  for (int i = 0; i < 5; ++i) {
    const bool tangential = i == 2 || i == 3;
    const double bound = tangential ? kMaxTangentialDistortion : kMaxRadialDistortion;
    if (std::abs(distortion[i]) > bound) {
      Throw("{}: distortion {} = {} is beyond +-{} (OpenCV's k1, k2, p1, p2, k3 order?)", where,
            kNames[i], distortion[i], bound);
    }
  }
}

Eigen::Vector2d Camera::Distort(const Eigen::Vector2d& n) const {
  const double k1 = distortion[0], k2 = distortion[1], p1 = distortion[2], p2 = distortion[3],
               k3 = distortion[4];
  const double x = n.x(), y = n.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return Eigen::Vector2d(x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                         y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y);
}

Eigen::Vector2d Camera::Undistort(const Eigen::Vector2d& d) const {
  if (!HasDistortion()) return d;
  // Fixed-point iteration as OpenCV's undistortPoints; converges for the distortion of real
  // lenses within the image.
  Eigen::Vector2d n = d;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d error = Distort(n) - d;
    n -= error;
    if (error.squaredNorm() < 1e-24) break;
  }
  return n;
}

Eigen::Vector2d Camera::Project(const Eigen::Vector3d& p) const {
  const Eigen::Vector2d n = Distort(p.head<2>() / p.z());
  return Eigen::Vector2d(fx * n.x() + cx, fy * n.y() + cy);
}

Eigen::Vector2d Camera::Unproject(const Eigen::Vector2d& pixel) const {
  return Undistort(Eigen::Vector2d((pixel.x() - cx) / fx, (pixel.y() - cy) / fy));
}

Camera Camera::Scaled(double factor) const {
  Camera c = *this;
  c.width = static_cast<int>(std::lround(width * factor));
  c.height = static_cast<int>(std::lround(height * factor));
  c.fx *= factor;
  c.fy *= factor;
  // Pixel centres at integer coordinates: scaling maps centre (0,0) of the new image to the
  // original position (0.5/factor - 0.5).
  c.cx = (cx + 0.5) * factor - 0.5;
  c.cy = (cy + 0.5) * factor - 0.5;
  return c;
}

bool Camera::operator==(const Camera& o) const {
  return width == o.width && height == o.height && fx == o.fx && fy == o.fy && cx == o.cx &&
         cy == o.cy && distortion == o.distortion;
}

}  // namespace epiloc
