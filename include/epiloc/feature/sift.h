// SIFT extraction (OpenCV's implementation, Lowe 2004) into epiloc's feature storage types.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "epiloc/feature/types.h"

namespace epiloc {

struct SiftOptions {
  // Keep at most this many features, strongest response first (0 = all).
  int max_num_features = 4000;
  // Images whose longer side exceeds this are downscaled for detection; keypoints are returned
  // in the original image's pixel coordinates (0 = never downscale).
  int max_image_size = 1600;
  // Detect in Lowe's upsampled octave (-1) too: the image doubled before the pyramid, which
  // finds the finest-scale features but costs about three times the rest of the pyramid. When
  // false the (possibly downscaled) image is halved first, so OpenCV's doubling restores its
  // resolution: the result is octaves 0, 1, ... of the image, in its pixel coordinates.
  bool upsampled_octave = true;
  // Scale-space layers per octave (Lowe: 3).
  int num_octave_layers = 3;
  // Contrast threshold on the DoG response; lower finds more features in low-contrast images
  // (OpenCV default 0.04; 0.02 keeps more of the weak but stable road-scene features).
  double contrast_threshold = 0.02;
  // Edge-response threshold (ratio of principal curvatures, Lowe: 10).
  double edge_threshold = 10.0;
  // Gaussian blur of the base image (Lowe: 1.6).
  double sigma = 1.6;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// Extracts SIFT features from an 8-bit grey or colour image (colour is converted to grey).
// Throws Error for an empty image or an unsupported pixel type.
FeatureSet ExtractSift(const cv::Mat& image, const SiftOptions& options);

// OpenCV's SIFT (4.6) doubles the image with pixel centres mapping x_doubled = 2 x + 0.5 but
// reports x_doubled / 2 (sift.dispatch.cpp: createInitialImage and the keypoint scale 0.5): its
// keypoint coordinates are 0.25 px too large in x and y (opencv#23123). Added to them, they sit
// on the image's pixel grid (centres at integers); ExtractSift does so.
constexpr double kOpenCvSiftOffsetPx = -0.25;

// The smallest keypoint size (diameter, pixels of the input image) ExtractSift can return for a
// width x height image with these options: OpenCV reports size = 2 * sigma * 2^((layer + offset) /
// num_octave_layers) per octave above the upsampled one, with layer >= 1 and offset >= -0.5.
double SmallestKeypointSizePx(const SiftOptions& options, int width, int height);

// 8-bit grey view of an image: colour converted (BGR order), 16-bit scaled to 8-bit.
cv::Mat ToGrey8(const cv::Mat& image);

}  // namespace epiloc
