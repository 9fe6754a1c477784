#include "epiloc/feature/sift.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Dark blobs on a light background at known centres: SIFT finds a keypoint at each centre.
cv::Mat BlobImage(int width, int height, const std::vector<cv::Point2d>& centres, double radius) {
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(200));
  for (const auto& c : centres) {
    // Shift 4 bits for sub-pixel accurate drawing of the centre.
    cv::circle(image, cv::Point(static_cast<int>(std::lround(c.x * 16)),
                                static_cast<int>(std::lround(c.y * 16))),
               static_cast<int>(radius * 16), cv::Scalar(30), cv::FILLED, cv::LINE_AA, 4);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.0);
  return image;
}

cv::Mat TextureImage(int width, int height, uint64_t seed) {
  std::mt19937_64 rng(seed);
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(128));
  std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1), r(2, 12), v(0, 255);
  for (int i = 0; i < 1500; ++i) {
    cv::circle(image, cv::Point(x(rng), y(rng)), r(rng), cv::Scalar(v(rng)), cv::FILLED);
  }
  return image;
}

double NearestKeypointDistance(const FeatureSet& features, const cv::Point2d& p) {
  double best = 1e9;
  for (int i = 0; i < features.size(); ++i) {
    best = std::min(best, std::hypot(features.keypoints(i, 0) - p.x, features.keypoints(i, 1) - p.y));
  }
  return best;
}

TEST(Sift, FindsBlobCentresInOriginalPixelCoordinates) {
  const std::vector<cv::Point2d> centres = {{200.3, 150.7}, {600.5, 400.25}, {1400.8, 800.4},
                                            {1000.0, 300.0}};
  const cv::Mat image = BlobImage(1800, 1000, centres, 14.0);
  SiftOptions full;
  full.max_image_size = 0;
  SiftOptions half;
  half.max_image_size = 900;  // detection on a half-size image
  for (const SiftOptions& options : {full, half}) {
    const FeatureSet features = ExtractSift(image, options);
    ASSERT_GE(features.size(), static_cast<int>(centres.size()));
    for (const auto& c : centres) {
      EXPECT_LT(NearestKeypointDistance(features, c), 0.15)
          << "blob at " << c << " max_image_size " << options.max_image_size;
    }
  }
}

TEST(Sift, KeepsStrongestUpToLimitAndFillsDescriptors) {
  const cv::Mat image = TextureImage(640, 480, 7);
  SiftOptions options;
  options.max_num_features = 0;
  const FeatureSet all = ExtractSift(image, options);
  ASSERT_GT(all.size(), 300);
  options.max_num_features = 200;
  const FeatureSet limited = ExtractSift(image, options);
  // OpenCV keeps ties at the cut-off, so allow a few more.
  EXPECT_GE(limited.size(), 200);
  EXPECT_LE(limited.size(), 210);
  EXPECT_EQ(limited.descriptors.rows(), limited.keypoints.rows());
  // Strongest first: the limited set is the prefix of the full set (same detections).
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(limited.keypoints.row(i), all.keypoints.row(i)) << "row " << i;
    EXPECT_EQ(limited.descriptors.row(i), all.descriptors.row(i)) << "row " << i;
  }
  for (int i = 0; i < limited.size(); ++i) {
    EXPECT_GT(limited.descriptors.row(i).cast<int>().sum(), 0);
    EXPECT_GE(limited.keypoints(i, 0), -0.5f);
    EXPECT_LT(limited.keypoints(i, 0), 639.5f);
    EXPECT_GT(limited.keypoints(i, 2), 0.0f);
  }
}

TEST(Sift, ColourAnd16BitImagesGiveTheSameFeaturesAsGrey) {
  const cv::Mat grey = TextureImage(320, 240, 3);
  cv::Mat colour, wide;
  cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
  grey.convertTo(wide, CV_16U, 257.0);
  const SiftOptions options;
  const FeatureSet a = ExtractSift(grey, options);
  const FeatureSet b = ExtractSift(colour, options);
  const FeatureSet c = ExtractSift(wide, options);
  ASSERT_GT(a.size(), 50);
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.size(), c.size());
  EXPECT_TRUE(a.keypoints.isApprox(b.keypoints));
  EXPECT_TRUE(a.keypoints.isApprox(c.keypoints));
}

// Without the upsampled octave the image is halved first: no keypoint is finer than
// SmallestKeypointSizePx (twice the upsampled octave's), blob centres still land in original
// pixel coordinates, and the finest keypoints found come close to the bound.
TEST(Sift, WithoutUpsampledOctaveSizesStayAboveTheBound) {
  const cv::Mat image = TextureImage(640, 360, 7);
  for (bool upsampled : {true, false}) {
    SiftOptions options;
    options.max_num_features = 0;
    options.upsampled_octave = upsampled;
    const double bound = SmallestKeypointSizePx(options, image.cols, image.rows);
    EXPECT_NEAR(bound, (upsampled ? 1.0 : 2.0) * 1.6 * std::pow(2.0, 0.5 / 3), 1e-12);
    const FeatureSet features = ExtractSift(image, options);
    ASSERT_GT(features.size(), 100);
    const float smallest = features.keypoints.col(2).minCoeff();
    EXPECT_GE(smallest, bound * 0.999) << "upsampled " << upsampled;
    EXPECT_LT(smallest, bound * 1.3) << "upsampled " << upsampled;
  }
  const std::vector<cv::Point2d> centres = {{100.25, 80.5}, {300.75, 200.0}, {500.5, 120.25}};
  SiftOptions half;
  half.upsampled_octave = false;
  const FeatureSet blobs = ExtractSift(BlobImage(640, 360, centres, 9.0), half);
  for (const cv::Point2d& c : centres) EXPECT_LT(NearestKeypointDistance(blobs, c), 0.15);
  // Downscaling for a size limit multiplies the bound by the inverse of the scale.
  half.max_image_size = 320;
  EXPECT_NEAR(SmallestKeypointSizePx(half, 640, 360), 4.0 * 1.6 * std::pow(2.0, 0.5 / 3), 1e-12);
}

TEST(Sift, RejectsInvalidInput) {
  EXPECT_THROW(ExtractSift(cv::Mat(), SiftOptions()), Error);
  EXPECT_THROW(ExtractSift(cv::Mat(10, 10, CV_32FC1, cv::Scalar(0)), SiftOptions()), Error);
  SiftOptions bad;
  bad.contrast_threshold = -1;
  EXPECT_THROW(bad.Check(), Error);
  bad = SiftOptions();
  bad.max_image_size = 10;
  EXPECT_THROW(bad.Check(), Error);
}

}  // namespace
}  // namespace epiloc
