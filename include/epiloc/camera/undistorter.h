// Removes lens distortion from whole images (OpenCV remap with precomputed maps).
#pragma once

#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"

namespace epiloc {

class Undistorter {
 public:
  // Maps images of `distorted` to a distortion-free pinhole camera of the same size whose
  // intrinsics keep only valid pixels (OpenCV getOptimalNewCameraMatrix with alpha = 0). A camera
  // without distortion passes images through unchanged.
  //
  // With `max_focal_px` > 0 the output is also reduced, field of view unchanged, until its focal
  // length is at most that (a working resolution: a query finer than the database it is matched
  // with adds pixels, not matches). One remap does both; a reduction by more than 2 averages
  // pixels first (no aliasing).
  explicit Undistorter(const Camera& distorted, double max_focal_px = 0.0);

  const Camera& distorted_camera() const { return distorted_; }
  // The pinhole camera of the undistorted images (distortion all zero).
  const Camera& undistorted_camera() const { return undistorted_; }
  // Output pixels per input pixel (1 unless max_focal_px reduced the images).
  double scale() const { return scale_; }

  // Throws Error if the image size differs from the camera's.
  cv::Mat Undistort(const cv::Mat& image) const;

 private:
  Camera distorted_;
  Camera undistorted_;
  double scale_ = 1.0;     // output pixels per input pixel
  double prescale_ = 1.0;  // area reduction before the remap (scale_ < 0.5)
  cv::Mat map_x_, map_y_;  // CV_16SC2 and CV_16UC1 fixed-point maps
};

}  // namespace epiloc
