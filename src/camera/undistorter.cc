#include "epiloc/camera/undistorter.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"

namespace epiloc {

Undistorter::Undistorter(const Camera& distorted) : distorted_(distorted), undistorted_(distorted) {
  distorted_.Check("camera");
  undistorted_.distortion.fill(0.0);
  if (!distorted_.HasDistortion()) return;
  const cv::Size size(distorted_.width, distorted_.height);
  cv::Mat k = (cv::Mat_<double>(3, 3) << distorted_.fx, 0, distorted_.cx, 0, distorted_.fy,
               distorted_.cy, 0, 0, 1);
  cv::Mat d(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) d.at<double>(i) = distorted_.distortion[i];
  const cv::Mat new_k = cv::getOptimalNewCameraMatrix(k, d, size, 0.0, size);
  undistorted_.fx = new_k.at<double>(0, 0);
  undistorted_.fy = new_k.at<double>(1, 1);
  undistorted_.cx = new_k.at<double>(0, 2);
  undistorted_.cy = new_k.at<double>(1, 2);
  cv::initUndistortRectifyMap(k, d, cv::Mat(), new_k, size, CV_32FC1, map_x_, map_y_);
}

cv::Mat Undistorter::Undistort(const cv::Mat& image) const {
  EPILOC_CHECK(image.cols == distorted_.width && image.rows == distorted_.height,
               "image of {}x{} pixels, the camera calibration says {}x{}", image.cols, image.rows,
               distorted_.width, distorted_.height);
  if (map_x_.empty()) return image;
  cv::Mat out;
  cv::remap(image, out, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return out;
}

}  // namespace epiloc
