// Feature matching between a camera frame and a rendering of the map (Kurobe et al., "Matching":
// AKAZE features, which match even the sparse, feature-poor renderings of a point cloud; SIFT as
// an option), with Lowe's ratio test and a RANSAC fundamental matrix (OpenCV USAC MAGSAC) to drop
// matches inconsistent with a rigid scene.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace epiloc {

enum class FeatureType { kAkaze, kSift };
// "akaze", "sift"; ParseFeatureType throws Error for another name.
std::string FeatureTypeName(FeatureType type);
FeatureType ParseFeatureType(const std::string& name);

struct ImageMatchOptions {
  FeatureType type = FeatureType::kAkaze;  // detector and descriptor
  double scale = 1.0;               // images are resized by this before detection (keypoints are
                                    // reported in full-resolution pixels)
  double blur_sigma_px = 0.0;       // Gaussian blur before detection (at the detection scale)
  double akaze_threshold = 0.0003;  // AKAZE detector response threshold (OpenCV default 0.001)
  int max_features = 5000;          // strongest features kept per image (0 = all)
  double ratio = 0.8;               // Lowe's ratio test: best / second-best descriptor distance
  double fundamental_threshold_px = 3.0;  // RANSAC F inlier threshold (0 = no F test)
  // Guided matching (used once a pose is close): a frame feature is matched only to rendered
  // features within this many pixels of its own position (0 = anywhere).
  double search_radius_px = 0.0;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// Features of one 8-bit grey image.
struct ImageFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  // one row per keypoint (CV_8U for AKAZE, CV_32F for SIFT)
};

// The features at `rows` (indices into features.keypoints), in that order.
ImageFeatures SelectFeatures(const ImageFeatures& features, const std::vector<int>& rows);

// Detects and describes features of `grey` (CV_8UC1) where `mask` (CV_8UC1, optional) is
// non-zero, keeping the max_features strongest.
ImageFeatures ExtractFeatures(const cv::Mat& grey,
                              const ImageMatchOptions& options,
                              const cv::Mat& mask = cv::Mat());

struct ImageMatches {
  std::vector<int> frame_index;   // index into the frame's keypoints
  std::vector<int> render_index;  // index into the rendering's keypoints
  int num_ratio = 0;              // matches passing the ratio test
  int num_geometric = 0;          // of those, consistent with the fundamental matrix
};

// Matches frame features to rendered features (ratio test, optionally guided, then F RANSAC).
ImageMatches MatchFeatures(const ImageFeatures& frame,
                           const ImageFeatures& render,
                           const ImageMatchOptions& options);

}  // namespace epiloc
