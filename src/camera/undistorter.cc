#include "epiloc/camera/undistorter.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

cv::Mat Intrinsics(const Camera& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}

// The camera of `c`'s images resized to width x height as cv::resize does it: the pixel grid
// stretched by each axis' own ratio of sizes, edges onto edges.
Camera Resized(Camera c, int width, int height) {
  const double sx = static_cast<double>(width) / c.width;
  const double sy = static_cast<double>(height) / c.height;
  c.fx *= sx;
  c.fy *= sy;
  c.cx = (c.cx + 0.5) * sx - 0.5;
  c.cy = (c.cy + 0.5) * sy - 0.5;
  c.width = width;
  c.height = height;
  return c;
}

}  // namespace

Undistorter::Undistorter(const Camera& distorted, double max_focal_px)
    : distorted_(distorted), undistorted_(distorted) {
  distorted_.Check("camera");
  EPILOC_CHECK(max_focal_px >= 0 && std::isfinite(max_focal_px),
               "undistorter: max_focal_px must be finite and >= 0, got {}", max_focal_px);
  undistorted_.distortion.fill(0.0);
  const cv::Size size(distorted_.width, distorted_.height);
  if (distorted_.HasDistortion()) {
    cv::Mat d(1, 5, CV_64F);
    for (int i = 0; i < 5; ++i) d.at<double>(i) = distorted_.distortion[i];
    const cv::Mat new_k = cv::getOptimalNewCameraMatrix(Intrinsics(distorted_), d, size, 0.0, size);
    undistorted_.fx = new_k.at<double>(0, 0);
    undistorted_.fy = new_k.at<double>(1, 1);
    undistorted_.cx = new_k.at<double>(0, 2);
    undistorted_.cy = new_k.at<double>(1, 2);
  }
  const double focal = std::max(undistorted_.fx, undistorted_.fy);
  if (max_focal_px > 0 && focal > max_focal_px) scale_ = max_focal_px / focal;
  if (scale_ < 1.0) {
    undistorted_ = undistorted_.Scaled(scale_);
  }
  if (!distorted_.HasDistortion() && scale_ >= 1.0) return;  // images pass unchanged

  // Shrinking by more than 2 by interpolation alone would alias: the input is first reduced by
  // area averaging to twice the output's resolution, and the maps start from that camera.
  Camera source = distorted_;
  if (scale_ < 0.5) {
    prescale_ = 2.0 * scale_;
    const Camera reduced = distorted_.Scaled(prescale_);
    source = Resized(distorted_, reduced.width, reduced.height);
  }
  cv::Mat d(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) d.at<double>(i) = distorted_.distortion[i];
  // Fixed-point maps (CV_16SC2 + interpolation table): remap runs about twice as fast as with
  // float maps, at 1/32 pixel resolution.
  cv::initUndistortRectifyMap(Intrinsics(source), d, cv::Mat(), Intrinsics(undistorted_),
                              cv::Size(undistorted_.width, undistorted_.height), CV_16SC2, map_x_,
                              map_y_);
}

cv::Mat Undistorter::Undistort(const cv::Mat& image) const {
  EPILOC_CHECK(image.cols == distorted_.width && image.rows == distorted_.height,
               "image of {}x{} pixels, the camera calibration says {}x{}", image.cols, image.rows,
               distorted_.width, distorted_.height);
  if (map_x_.empty()) return image;
  cv::Mat source = image;
  if (prescale_ < 1.0) {
    const Camera reduced = distorted_.Scaled(prescale_);
    cv::resize(image, source, cv::Size(reduced.width, reduced.height), 0, 0, cv::INTER_AREA);
  }
  cv::Mat out;
  cv::remap(source, out, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return out;
}

}  // namespace epiloc
