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
  explicit Undistorter(const Camera& distorted);

  const Camera& distorted_camera() const { return distorted_; }
  // The pinhole camera of the undistorted images (distortion all zero).
  const Camera& undistorted_camera() const { return undistorted_; }

  // Throws Error if the image size differs from the camera's.
  cv::Mat Undistort(const cv::Mat& image) const;

 private:
  Camera distorted_;
  Camera undistorted_;
  cv::Mat map_x_, map_y_;
};

}  // namespace epiloc
