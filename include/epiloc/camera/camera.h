// Pinhole camera with OpenCV's 5-coefficient radial-tangential distortion.
//
// Pixel convention: the centre of the top-left pixel is (0, 0), as in OpenCV and KITTI's P_rect
// matrices; x to the right, y down. Camera frame: x right, y down, z forward (optical axis).
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>

namespace epiloc {

struct Camera {
  int width = 0;   // image size in pixels
  int height = 0;
  double fx = 0.0;  // focal lengths, pixels
  double fy = 0.0;
  double cx = 0.0;  // principal point, pixels
  double cy = 0.0;
  // OpenCV order k1, k2, p1, p2, k3; all zero for rectified or undistorted images.
  std::array<double, 5> distortion{};

  bool HasDistortion() const;
  Eigen::Matrix3d K() const;

  // Sane bounds checked by Check(): a side below kMaxImageSide pixels, a focal length between
  // kMinFocalPerSide and kMaxFocalPerSide times the longer side, |k1|, |k2|, |k3| up to
  // kMaxRadialDistortion and |p1|, |p2| up to kMaxTangentialDistortion.
  static constexpr int kMaxImageSide = 100000;
  static constexpr double kMinFocalPerSide = 0.02;
  static constexpr double kMaxFocalPerSide = 200.0;
  static constexpr double kMaxRadialDistortion = 1000.0;
  static constexpr double kMaxTangentialDistortion = 1.0;

  // Throws Error (prefixed with `where`) if a value is invalid: non-positive size or focal
  // length, non-finite value, principal point outside the image, a value beyond the sane bounds
  // above, fy / fx outside [0.5, 2] or a radial distortion not invertible over the image (.cc).
  void Check(const std::string& where) const;

  // Projects a point in the camera frame (z > 0) to distorted pixel coordinates.
  Eigen::Vector2d Project(const Eigen::Vector3d& point_in_cam) const;
  // Normalised image coordinates (x/z, y/z) of the ray through a distorted pixel
  // (iterative inversion of the distortion model).
  Eigen::Vector2d Unproject(const Eigen::Vector2d& pixel) const;

  // Applies / removes the distortion on normalised coordinates.
  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;
  Eigen::Vector2d Undistort(const Eigen::Vector2d& distorted_normalized) const;

  // The same camera with its images scaled by `factor` (e.g. 0.5 halves the resolution).
  Camera Scaled(double factor) const;

  bool operator==(const Camera& other) const;
};

}  // namespace epiloc
