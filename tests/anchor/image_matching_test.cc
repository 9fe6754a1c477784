// Feature extraction for the rendering and photograph anchor methods: keypoints in the frame's
// own pixel coordinates (pixel centres at integers), whatever the detection scale.
#include "epiloc/anchor/image_matching.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace epiloc {
namespace {

// Dark discs on a light background at known sub-pixel centres.
cv::Mat BlobImage(int width, int height, const std::vector<cv::Point2d>& centres, double radius) {
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(200));
  for (const cv::Point2d& c : centres) {
    // 4 fractional bits: the centre drawn to 1/16 px.
    cv::circle(image,
               cv::Point(static_cast<int>(std::lround(c.x * 16)),
                         static_cast<int>(std::lround(c.y * 16))),
               static_cast<int>(radius * 16), cv::Scalar(30), cv::FILLED, cv::LINE_AA, 4);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.0);
  return image;
}

double NearestKeypointDistance(const ImageFeatures& features, const cv::Point2d& p) {
  double best = 1e9;
  for (const cv::KeyPoint& k : features.keypoints) {
    best = std::min(best, std::hypot(k.pt.x - p.x, k.pt.y - p.y));
  }
  return best;
}

// SIFT at full and half detection scale: each disc's keypoint within 0.15 px of its centre
// (OpenCV's own coordinates are 0.25 px off in x and y, 0.35 px in all).
TEST(ImageMatching, SiftKeypointsSitOnTheBlobCentres) {
  const std::vector<cv::Point2d> centres = {{200.3, 150.7}, {600.5, 400.25}, {1000.0, 300.0},
                                            {1400.8, 800.4}};
  const cv::Mat image = BlobImage(1800, 1000, centres, 14.0);
  for (const double scale : {1.0, 0.5}) {
    ImageMatchOptions options;
    options.type = FeatureType::kSift;
    options.max_features = 0;
    options.scale = scale;
    const ImageFeatures features = ExtractFeatures(image, options);
    ASSERT_GE(features.keypoints.size(), centres.size());
    for (const cv::Point2d& c : centres) {
      EXPECT_LT(NearestKeypointDistance(features, c), 0.15) << c << " scale " << scale;
    }
  }
}

}  // namespace
}  // namespace epiloc
