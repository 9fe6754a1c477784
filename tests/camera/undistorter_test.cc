// The undistorter on images with known content: bright spots at the projections of known points
// must land at their projections in the output camera, at full and at a working resolution.
#include "epiloc/camera/undistorter.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "camera_test_util.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

Camera PinholeCamera() {
  Camera camera = KittiCamera();
  camera.distortion.fill(0.0);
  return camera;
}

const std::vector<Eigen::Vector3d>& Points() {
  static const std::vector<Eigen::Vector3d> points = {
      {0.0, 0.0, 10.0}, {2.5, 0.8, 10.0}, {-3.0, -0.9, 12.0}, {4.0, -1.0, 14.0}, {-1.5, 1.2, 8.0}};
  return points;
}

// A float image of Gaussian spots (sigma 3 px) at the points' projections.
cv::Mat Spots(const Camera& camera) {
  cv::Mat image(camera.height, camera.width, CV_32F, cv::Scalar(0));
  for (const Eigen::Vector3d& point : Points()) {
    const Eigen::Vector2d p = camera.Project(point);
    for (int y = std::max(0, static_cast<int>(p.y()) - 15);
         y <= std::min(camera.height - 1, static_cast<int>(p.y()) + 15); ++y) {
      for (int x = std::max(0, static_cast<int>(p.x()) - 15);
           x <= std::min(camera.width - 1, static_cast<int>(p.x()) + 15); ++x) {
        const double r2 = (x - p.x()) * (x - p.x()) + (y - p.y()) * (y - p.y());
        image.at<float>(y, x) += static_cast<float>(std::exp(-r2 / (2 * 9.0)));
      }
    }
  }
  return image;
}

// The intensity centroid within `radius` of `near`.
Eigen::Vector2d Centroid(const cv::Mat& image, const Eigen::Vector2d& near, double radius) {
  double sum = 0, sx = 0, sy = 0;
  for (int y = std::max(0, static_cast<int>(near.y() - radius));
       y <= std::min(image.rows - 1, static_cast<int>(near.y() + radius)); ++y) {
    for (int x = std::max(0, static_cast<int>(near.x() - radius));
         x <= std::min(image.cols - 1, static_cast<int>(near.x() + radius)); ++x) {
      const double v = image.at<float>(y, x);
      sum += v;
      sx += v * x;
      sy += v * y;
    }
  }
  return Eigen::Vector2d(sx / sum, sy / sum);
}

void ExpectSpotsAtProjections(const Undistorter& undistorter, double tolerance_px) {
  const cv::Mat out = undistorter.Undistort(Spots(undistorter.distorted_camera()));
  const Camera& camera = undistorter.undistorted_camera();
  ASSERT_EQ(out.cols, camera.width);
  ASSERT_EQ(out.rows, camera.height);
  for (const Eigen::Vector3d& point : Points()) {
    const Eigen::Vector2d expected = camera.Project(point);
    const Eigen::Vector2d found = Centroid(out, expected, 4.0 * 3.0 * undistorter.scale() + 3);
    EXPECT_LT((found - expected).norm(), tolerance_px)
        << "point " << point.transpose() << ": expected " << expected.transpose() << ", found "
        << found.transpose();
  }
}

TEST(Undistorter, SpotsLandAtTheirPinholeProjections) {
  const Undistorter undistorter(KittiCamera());
  EXPECT_EQ(undistorter.scale(), 1.0);
  EXPECT_EQ(undistorter.undistorted_camera().width, 1392);
  ExpectSpotsAtProjections(undistorter, 0.1);
}

TEST(Undistorter, WorkingResolutionKeepsTheGeometry) {
  // Without distortion: a plain reduction to focal 600.
  const Undistorter pinhole(PinholeCamera(), 600.0);
  EXPECT_NEAR(pinhole.undistorted_camera().fx, 600.0, 1e-9);
  EXPECT_NEAR(pinhole.scale(), 600.0 / 984.0, 1e-12);
  EXPECT_EQ(pinhole.undistorted_camera().width, 849);  // 1392 * 0.61
  ExpectSpotsAtProjections(pinhole, 0.1);
  // With distortion, reduced by more than 2 (area averaging first).
  const Undistorter small(KittiCamera(), 300.0);
  EXPECT_LT(small.scale(), 0.5);
  EXPECT_LE(small.undistorted_camera().fx, 300.0 + 1e-9);
  ExpectSpotsAtProjections(small, 0.15);
  // A limit above the focal length changes nothing.
  const Undistorter same(PinholeCamera(), 2000.0);
  EXPECT_EQ(same.scale(), 1.0);
  const cv::Mat image = Spots(PinholeCamera());
  EXPECT_EQ(same.Undistort(image).data, image.data);  // passed through, not copied
}

TEST(Undistorter, BadInput) {
  const Undistorter undistorter(KittiCamera());
  EXPECT_THROW(undistorter.Undistort(cv::Mat(100, 100, CV_8U)), Error);
  EXPECT_THROW(Undistorter(KittiCamera(), -1.0), Error);
  EXPECT_THROW(Undistorter(KittiCamera(), NAN), Error);
}

}  // namespace
}  // namespace epiloc
