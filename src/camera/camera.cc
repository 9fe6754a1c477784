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

namespace {

// fy / fx within [kMinFocalRatio, kMaxFocalRatio]: pixels are square or nearly so on every real
// sensor (anamorphic video formats stretch by 4:3 at most); beyond it is a typo (a digit lost or
// added, fx and fy of two cameras mixed).
constexpr double kMinFocalRatio = 0.5;
constexpr double kMaxFocalRatio = 2.0;
// The radial factor stays below this out to the image corner: real pincushion lenses stretch by a
// few percent; a factor of 4 is a model extrapolated far beyond any calibration data.
constexpr double kMaxRadialFactor = 4.0;

// Undistortion maps each pixel of the undistorted image, through its undistorted normalised
// coordinates, to the distorted image (Distort). The undistorted camera has about the distorted
// one's intrinsics (getOptimalNewCameraMatrix with alpha 0 only crops inward), so it sees
// normalised radii out to about the distorted image's corner radius; over that range the radial
// map r -> r (1 + k1 r^2 + k2 r^4 + k3 r^6) must be one-to-one: increasing in r, and the factor
// positive (a negative factor mirrors the point through the centre). Where it folds over, two
// undistorted radii show the same pixel and the inverse (Undistort) converges to either or to
// neither. Sampled finely enough for the polynomials of real lenses; the tangential terms are
// bounded by kMaxTangentialDistortion.
void CheckRadialDistortion(const Camera& camera, const std::string& where) {
  const double k1 = camera.distortion[0], k2 = camera.distortion[1], k3 = camera.distortion[4];
  if (k1 == 0 && k2 == 0 && k3 == 0) return;
  double corner = 0.0;
  for (const double x : {-0.5, camera.width - 0.5}) {
    for (const double y : {-0.5, camera.height - 0.5}) {
      corner =
          std::max(corner, std::hypot((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy));
    }
  }
  constexpr int kSteps = 2000;
  for (int i = 1; i <= kSteps; ++i) {
    const double r = corner * i / kSteps;
    const double r2 = r * r;
    const double factor = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double slope = 1.0 + r2 * (3 * k1 + r2 * (5 * k2 + r2 * 7 * k3));
    if (!(factor > 0) || !(slope > 0)) {
      Throw(
          "{}: distortion k1={} k2={} k3={} is not invertible over the image: the distorted "
          "radius {} at normalised radius {:.3f}, inside the image corner's {:.3f}",
          where, k1, k2, k3, factor > 0 ? "stops growing" : "changes sign", r, corner);
    }
    if (factor > kMaxRadialFactor) {
      Throw(
          "{}: distortion k1={} k2={} k3={} stretches the image {:.3g} times at normalised "
          "radius {:.3f} (image corner {:.3f}), beyond the {} of any real lens",
          where, k1, k2, k3, factor, r, corner, kMaxRadialFactor);
    }
  }
}

}  // namespace

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
  const double ratio = fy / fx;
  if (ratio < kMinFocalRatio || ratio > kMaxFocalRatio) {
    Throw(
        "{}: fy / fx = {:.4g} (fx {} px, fy {} px) is outside [{}, {}]: pixels are square or "
        "nearly so on every real sensor",
        where, ratio, fx, fy, kMinFocalRatio, kMaxFocalRatio);
  }
  CheckRadialDistortion(*this, where);
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
