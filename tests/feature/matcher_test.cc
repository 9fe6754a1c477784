#include "epiloc/feature/matcher.h"

#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/feature/sift.h"

namespace epiloc {
namespace {

cv::Mat Texture(int width, int height, uint64_t seed) {
  std::mt19937_64 rng(seed);
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(128));
  std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1), r(2, 14), v(0, 255);
  for (int i = 0; i < 2500; ++i) {
    cv::circle(image, cv::Point(x(rng), y(rng)), r(rng), cv::Scalar(v(rng)), cv::FILLED);
  }
  return image;
}

TEST(Matcher, MatchesFollowAKnownImageMotion) {
  const cv::Mat a = Texture(800, 500, 1);
  // b = a rotated by 5 degrees, scaled by 1.1 about the centre, shifted by (12, -7) pixels.
  cv::Mat motion = cv::getRotationMatrix2D(cv::Point2f(400, 250), 5.0, 1.1);
  motion.at<double>(0, 2) += 12;
  motion.at<double>(1, 2) -= 7;
  cv::Mat b;
  cv::warpAffine(a, b, motion, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const FeatureSet fa = ExtractSift(a, SiftOptions());
  const FeatureSet fb = ExtractSift(b, SiftOptions());
  const DescriptorIndex index(fa.descriptors, MatchOptions());
  const std::vector<FeatureMatch> matches = index.Match(fb.descriptors);
  ASSERT_GT(matches.size(), 300u);
  int correct = 0;
  std::vector<char> used(fa.size(), 0);
  for (const FeatureMatch& m : matches) {
    ASSERT_FALSE(used[m.index_a]) << "indexed feature matched twice";
    used[m.index_a] = 1;
    const double xa = fa.keypoints(m.index_a, 0), ya = fa.keypoints(m.index_a, 1);
    const double xb = motion.at<double>(0, 0) * xa + motion.at<double>(0, 1) * ya +
                      motion.at<double>(0, 2);
    const double yb = motion.at<double>(1, 0) * xa + motion.at<double>(1, 1) * ya +
                      motion.at<double>(1, 2);
    correct += std::hypot(xb - fb.keypoints(m.index_b, 0), yb - fb.keypoints(m.index_b, 1)) < 2.0;
  }
  EXPECT_GT(correct, 0.95 * matches.size());
}

TEST(Matcher, UnrelatedImagesGiveFewMatchesAndLimitsApply) {
  const FeatureSet fa = ExtractSift(Texture(640, 480, 2), SiftOptions());
  const FeatureSet fb = ExtractSift(Texture(640, 480, 3), SiftOptions());
  const DescriptorIndex index(fa.descriptors, MatchOptions(), 500);
  EXPECT_EQ(index.size(), 500);
  const std::vector<FeatureMatch> matches = index.Match(fb.descriptors, 500);
  EXPECT_LT(matches.size(), 50u);
  for (const FeatureMatch& m : matches) {
    EXPECT_LT(m.index_a, 500);
    EXPECT_LT(m.index_b, 500);
  }
  EXPECT_TRUE(DescriptorIndex(FeatureDescriptors(0, 128), MatchOptions()).Match(fb.descriptors).empty());
}

TEST(Matcher, RootSiftRowsHaveUnitLength) {
  FeatureDescriptors d(2, 128);
  d.setConstant(3);
  d.row(1).setZero();
  const std::vector<float> root = ToRootSift(d, 2);
  double norm2 = 0;
  for (int k = 0; k < 128; ++k) norm2 += root[k] * root[k];
  EXPECT_NEAR(norm2, 1.0, 1e-6);
  EXPECT_EQ(root[128], 0.0f);
  MatchOptions bad;
  bad.ratio = 1.5;
  EXPECT_THROW(bad.Check(), Error);
}

}  // namespace
}  // namespace epiloc
