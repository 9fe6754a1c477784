#include "epiloc/synth/camera_presets.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"
#include "epiloc/synth/trajectory.h"

namespace epiloc {
namespace {

// Radial distortion factor and the derivative of the distorted radius r * factor(r) in r.
double RadialSlope(const Camera& camera, double r) {
  const double k1 = camera.distortion[0], k2 = camera.distortion[1], k3 = camera.distortion[4];
  const double r2 = r * r;
  return 1.0 + r2 * (3 * k1 + r2 * (5 * k2 + r2 * 7 * k3));
}

// True if Undistort inverts Distort at the normalised distorted point.
bool Inverts(const Camera& camera, const Eigen::Vector2d& distorted) {
  const Eigen::Vector2d n = camera.Undistort(distorted);
  return n.allFinite() && (camera.Distort(n) - distorted).norm() < 1e-9;
}

}  // namespace

double HorizontalFovDeg(const Camera& camera) {
  const Eigen::Vector2d left = camera.Unproject(Eigen::Vector2d(-0.5, camera.cy));
  const Eigen::Vector2d right = camera.Unproject(Eigen::Vector2d(camera.width - 0.5, camera.cy));
  return (std::atan(right.x()) - std::atan(left.x())) / kDegToRad;
}

Camera WithHorizontalFovDeg(const Camera& camera, double hfov_deg) {
  EPILOC_CHECK(std::isfinite(hfov_deg) && hfov_deg > 1 && hfov_deg < 179,
               "camera: horizontal field of view {} deg must be in (1, 179)", hfov_deg);
  // The field of view shrinks as the focal length grows; where the distortion folds over (too
  // short a focal length) the edges see no ray and count as too wide. Bisection on log f.
  const auto too_wide = [&](double f) {
    Camera c = camera;
    c.fx = c.fy = f;
    for (const double x : {-0.5, c.width - 0.5}) {
      const Eigen::Vector2d d((x - c.cx) / f, 0.0);
      if (!Inverts(c, d) || RadialSlope(c, c.Undistort(d).norm()) <= 0) return true;
    }
    return HorizontalFovDeg(c) > hfov_deg;
  };
  double lo = std::log(1e-3 * camera.width), hi = std::log(1e3 * camera.width);
  EPILOC_CHECK(too_wide(std::exp(lo)) && !too_wide(std::exp(hi)),
               "camera: no focal length gives a {} deg field of view", hfov_deg);
  for (int i = 0; i < 200 && hi - lo > 1e-15; ++i) {
    const double mid = 0.5 * (lo + hi);
    (too_wide(std::exp(mid)) ? lo : hi) = mid;
  }
  Camera out = camera;
  out.fx = out.fy = std::exp(hi);
  EPILOC_CHECK(std::abs(HorizontalFovDeg(out) - hfov_deg) < 1e-6,
               "camera: the distortion cannot reach a {} deg field of view (at most {:.1f} deg)",
               hfov_deg, HorizontalFovDeg(out));
  return out;
}

Camera WithSize(const Camera& camera, int width, int height) {
  EPILOC_CHECK(width > 0 && height > 0, "camera: size {}x{} must be positive", width, height);
  Camera out = camera;
  const double scale = static_cast<double>(width) / camera.width;
  out.width = width;
  out.height = height;
  out.fx *= scale;
  out.fy *= scale;
  out.cx = 0.5 * width - 0.5;
  out.cy = 0.5 * height - 0.5;
  return out;
}

void CheckDistortionInvertible(const Camera& camera, const std::string& where) {
  if (!camera.HasDistortion()) return;
  double corner_radius = 0;  // distorted normalised radius of the farthest image corner
  for (const double x : {-0.5, camera.width - 0.5}) {
    for (const double y : {-0.5, camera.height - 0.5}) {
      const Eigen::Vector2d d((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy);
      corner_radius = std::max(corner_radius, d.norm());
      EPILOC_CHECK(Inverts(camera, d),
                   "{}: the distortion cannot be inverted at the image corner ({}, {})", where, x,
                   y);
    }
  }
  // The radial model r (1 + k1 r^2 + k2 r^4 + k3 r^6) must grow until it reaches the corners.
  const double k1 = camera.distortion[0], k2 = camera.distortion[1], k3 = camera.distortion[4];
  for (double r = 0;; r += 1e-3) {
    const double r2 = r * r;
    if (r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) >= corner_radius) break;
    EPILOC_CHECK(RadialSlope(camera, r) > 0 && r < 100,
                 "{}: the distortion folds over inside the image (at normalised radius {:.3f})",
                 where, r);
  }
}

std::vector<std::string> QueryCameraPresets() { return {"default", "dashcam1080", "vga"}; }

void ApplyQueryCameraPreset(const std::string& name, DriveOptions* drive) {
  EPILOC_CHECK(drive != nullptr, "camera preset: no drive");
  const DriveOptions query = DriveOptions::Query();
  if (name == "default") {
    drive->camera = query.camera;
    drive->frame_rate_hz = query.frame_rate_hz;
  } else if (name == "dashcam1080") {
    // A wide-angle dashcam: 120 deg horizontally (about 125 deg diagonally) with the strong
    // barrel distortion of such lenses; the distorted radius still grows out to the corners.
    Camera c;
    c.width = 1920;
    c.height = 1080;
    c.cx = 959.5;
    c.cy = 539.5;
    c.fx = c.fy = 800.0;
    c.distortion = {-0.2, 0.03, 0.0, 0.0, 0.0};
    drive->camera = WithHorizontalFovDeg(c, 120.0);
    drive->frame_rate_hz = 30.0;
  } else if (name == "vga") {
    Camera c;
    c.width = 640;
    c.height = 480;
    c.cx = 319.5;
    c.cy = 239.5;
    c.fx = c.fy = 550.0;
    c.distortion = {-0.05, 0.0, 0.0, 0.0, 0.0};
    drive->camera = WithHorizontalFovDeg(c, 60.0);
    drive->frame_rate_hz = 15.0;
  } else {
    Throw("camera preset '{}' is unknown (known: default, dashcam1080, vga)", name);
  }
}

}  // namespace epiloc
