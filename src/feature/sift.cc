#include "epiloc/feature/sift.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"

namespace epiloc {

void SiftOptions::Check() const {
  EPILOC_CHECK(max_num_features >= 0, "sift: max_num_features must be >= 0, got {}",
               max_num_features);
  EPILOC_CHECK(max_image_size == 0 || max_image_size >= 64,
               "sift: max_image_size must be 0 or >= 64, got {}", max_image_size);
  EPILOC_CHECK(num_octave_layers >= 1, "sift: num_octave_layers must be >= 1, got {}",
               num_octave_layers);
  EPILOC_CHECK(contrast_threshold > 0, "sift: contrast_threshold must be > 0, got {}",
               contrast_threshold);
  EPILOC_CHECK(edge_threshold > 1, "sift: edge_threshold must be > 1, got {}", edge_threshold);
  EPILOC_CHECK(sigma > 0, "sift: sigma must be > 0, got {}", sigma);
}

cv::Mat ToGrey8(const cv::Mat& image) {
  EPILOC_CHECK(!image.empty(), "empty image");
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  } else if (image.channels() == 1) {
    grey = image;
  } else {
    Throw("image with {} channels is not supported", image.channels());
  }
  if (grey.depth() == CV_16U) {
    grey.convertTo(grey, CV_8U, 1.0 / 257.0);
  } else if (grey.depth() != CV_8U) {
    Throw("image pixel depth {} is not supported (8 or 16 bit expected)", grey.depth());
  }
  return grey;
}

namespace {

// Scale factor ExtractSift applies to an image before OpenCV's SIFT.
double DetectionScale(const SiftOptions& options, int width, int height) {
  double scale = 1.0;
  const int longer = std::max(width, height);
  if (options.max_image_size > 0 && longer > options.max_image_size) {
    scale = static_cast<double>(options.max_image_size) / longer;
  }
  if (!options.upsampled_octave) scale *= 0.5;
  return scale;
}

}  // namespace

double SmallestKeypointSizePx(const SiftOptions& options, int width, int height) {
  options.Check();
  // In OpenCV's pyramid of the doubled image, octave o >= 0 reports sizes with a factor 2^o; the
  // doubled octave itself is halved back (factor 1/2), so its smallest size is sigma * 2^(0.5/n).
  const double smallest = options.sigma * std::pow(2.0, 0.5 / options.num_octave_layers);
  return smallest / DetectionScale(options, width, height);
}

FeatureSet ExtractSift(const cv::Mat& image, const SiftOptions& options) {
  options.Check();
  cv::Mat grey = ToGrey8(image);
  const double scale = DetectionScale(options, grey.cols, grey.rows);
  if (scale != 1.0) cv::resize(grey, grey, cv::Size(), scale, scale, cv::INTER_AREA);

  // OpenCV's nfeatures keeps the strongest responses; descriptors directly as uint8.
  auto sift =
      cv::SIFT::create(options.max_num_features, options.num_octave_layers,
                       options.contrast_threshold, options.edge_threshold, options.sigma, CV_8U);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  sift->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);

  // Strongest first, so a consumer can take the best N features as a prefix of the rows.
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  // Ties (one location with two orientations) broken by position and angle, so the order does
  // not depend on how many features were requested.
  std::sort(order.begin(), order.end(), [&keypoints](int a, int b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    return std::make_tuple(-ka.response, ka.pt.y, ka.pt.x, ka.size, ka.angle) <
           std::make_tuple(-kb.response, kb.pt.y, kb.pt.x, kb.size, kb.angle);
  });

  FeatureSet features;
  const int n = static_cast<int>(keypoints.size());
  features.keypoints.resize(n, 4);
  features.descriptors.resize(n, 128);
  // OpenCV's coordinates corrected (kOpenCvSiftOffsetPx); pixel centres sit at integer
  // coordinates in both images, so the downscale maps x -> (x + 0.5) / scale - 0.5.
  for (int i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = keypoints[order[i]];
    features.keypoints(i, 0) =
        static_cast<float>((kp.pt.x + kOpenCvSiftOffsetPx + 0.5) / scale - 0.5);
    features.keypoints(i, 1) =
        static_cast<float>((kp.pt.y + kOpenCvSiftOffsetPx + 0.5) / scale - 0.5);
    features.keypoints(i, 2) = static_cast<float>(kp.size / scale);
    features.keypoints(i, 3) = static_cast<float>(kp.angle * M_PI / 180.0);
  }
  if (n > 0) {
    EPILOC_CHECK(descriptors.type() == CV_8U && descriptors.cols == 128,
                 "sift: unexpected descriptor type {} with {} columns", descriptors.type(),
                 descriptors.cols);
    for (int i = 0; i < n; ++i) {
      std::copy(descriptors.ptr<uint8_t>(order[i]), descriptors.ptr<uint8_t>(order[i]) + 128,
                features.descriptors.row(i).data());
    }
  }
  return features;
}

}  // namespace epiloc
