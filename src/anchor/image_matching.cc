#include "epiloc/anchor/image_matching.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/feature/sift.h"

namespace epiloc {
namespace {

// Fewer ratio-test matches than this skip the F test (PnP RANSAC still checks them).
constexpr int kMinMatchesForFundamental = 15;

int NormType(const cv::Mat& descriptors) {
  return descriptors.depth() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
}

// Best and second-best render feature of frame feature i among `candidates` (all when empty).
struct Nearest {
  int index = -1;
  double best = INFINITY;
  double second = INFINITY;
};

Nearest FindNearest(const cv::Mat& query_row,
                    const cv::Mat& render_descriptors,
                    const std::vector<int>& candidates,
                    int norm_type) {
  Nearest n;
  for (const int j : candidates) {
    const double d = cv::norm(query_row, render_descriptors.row(j), norm_type);
    if (d < n.best) {
      n.second = n.best;
      n.best = d;
      n.index = j;
    } else if (d < n.second) {
      n.second = d;
    }
  }
  return n;
}

// Render features within `radius` pixels of each frame feature, from a grid of cells of that size.
class KeypointGrid {
 public:
  KeypointGrid(const std::vector<cv::KeyPoint>& keypoints, double radius)
      : keypoints_(keypoints), cell_(radius) {
    for (size_t i = 0; i < keypoints.size(); ++i) {
      cells_[Key(Cell(keypoints[i].pt.x), Cell(keypoints[i].pt.y))].push_back(static_cast<int>(i));
    }
  }
  std::vector<int> Near(const cv::Point2f& p) const {
    std::vector<int> out;
    const int cx = Cell(p.x), cy = Cell(p.y);
    const double r2 = cell_ * cell_;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const auto it = cells_.find(Key(cx + dx, cy + dy));
        if (it == cells_.end()) continue;
        for (const int j : it->second) {
          const cv::Point2f d = keypoints_[j].pt - p;
          if (d.dot(d) <= r2) out.push_back(j);
        }
      }
    }
    return out;
  }

 private:
  int Cell(float v) const { return static_cast<int>(std::floor(v / cell_)); }
  static int64_t Key(int x, int y) { return (static_cast<int64_t>(x) << 32) ^ (y & 0xffffffffLL); }

  const std::vector<cv::KeyPoint>& keypoints_;
  double cell_;
  std::unordered_map<int64_t, std::vector<int>> cells_;
};

}  // namespace

std::string FeatureTypeName(FeatureType type) {
  return type == FeatureType::kAkaze ? "akaze" : "sift";
}

FeatureType ParseFeatureType(const std::string& name) {
  if (name == "akaze") return FeatureType::kAkaze;
  if (name == "sift") return FeatureType::kSift;
  Throw("unknown matcher '{}' (known: akaze, sift)", name);
}

void ImageMatchOptions::Check() const {
  EPILOC_CHECK(std::isfinite(scale) && scale > 0 && scale <= 1,
               "match options: scale must be in (0, 1], got {}", scale);
  EPILOC_CHECK(std::isfinite(blur_sigma_px) && blur_sigma_px >= 0,
               "match options: blur_sigma_px must be >= 0, got {}", blur_sigma_px);
  EPILOC_CHECK(std::isfinite(akaze_threshold) && akaze_threshold > 0,
               "match options: akaze_threshold must be > 0, got {}", akaze_threshold);
  EPILOC_CHECK(max_features >= 0, "match options: max_features must be >= 0, got {}",
               max_features);
  EPILOC_CHECK(ratio > 0 && ratio <= 1, "--ratio must be in (0, 1], got {}", ratio);
  EPILOC_CHECK(std::isfinite(fundamental_threshold_px) && fundamental_threshold_px >= 0,
               "match options: fundamental_threshold_px must be >= 0, got {}",
               fundamental_threshold_px);
  EPILOC_CHECK(std::isfinite(search_radius_px) && search_radius_px >= 0,
               "match options: search_radius_px must be >= 0, got {}", search_radius_px);
}

ImageFeatures SelectFeatures(const ImageFeatures& features, const std::vector<int>& rows) {
  ImageFeatures out;
  out.keypoints.reserve(rows.size());
  out.descriptors.create(static_cast<int>(rows.size()), features.descriptors.cols,
                         features.descriptors.type());
  for (size_t k = 0; k < rows.size(); ++k) {
    out.keypoints.push_back(features.keypoints[rows[k]]);
    features.descriptors.row(rows[k]).copyTo(out.descriptors.row(static_cast<int>(k)));
  }
  return out;
}

ImageFeatures ExtractFeatures(const cv::Mat& grey,
                              const ImageMatchOptions& options,
                              const cv::Mat& mask) {
  EPILOC_CHECK(grey.type() == CV_8UC1, "ExtractFeatures: expected an 8-bit grey image");
  ImageFeatures features;
  cv::Ptr<cv::Feature2D> detector;
  if (options.type == FeatureType::kAkaze) {
    detector = cv::AKAZE::create(cv::AKAZE::DESCRIPTOR_MLDB, 0, 3,
                                 static_cast<float>(options.akaze_threshold));
  } else {
    detector = cv::SIFT::create(options.max_features);
  }
  cv::Mat image = grey, image_mask = mask;
  if (options.scale != 1.0) {
    cv::resize(grey, image, cv::Size(), options.scale, options.scale, cv::INTER_AREA);
    if (!mask.empty()) cv::resize(mask, image_mask, image.size(), 0, 0, cv::INTER_NEAREST);
  }
  if (options.blur_sigma_px > 0) {
    cv::GaussianBlur(image, image, cv::Size(), options.blur_sigma_px);
  }
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  detector->detectAndCompute(image, image_mask, keypoints, descriptors);
  if (options.type == FeatureType::kSift) {
    const float offset = static_cast<float>(kOpenCvSiftOffsetPx);
    for (cv::KeyPoint& k : keypoints) k.pt += cv::Point2f(offset, offset);
  }
  if (options.scale != 1.0) {
    const float s = static_cast<float>(1.0 / options.scale);
    for (cv::KeyPoint& k : keypoints) {
      k.pt = (k.pt + cv::Point2f(0.5f, 0.5f)) * s - cv::Point2f(0.5f, 0.5f);
      k.size *= s;
    }
  }
  if (options.max_features > 0 && static_cast<int>(keypoints.size()) > options.max_features) {
    std::vector<int> order(keypoints.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return keypoints[a].response > keypoints[b].response;
    });
    order.resize(options.max_features);
    std::sort(order.begin(), order.end());
    return SelectFeatures({std::move(keypoints), descriptors}, order);
  } else {
    features.keypoints = std::move(keypoints);
    features.descriptors = descriptors;
  }
  return features;
}

ImageMatches MatchFeatures(const ImageFeatures& frame,
                           const ImageFeatures& render,
                           const ImageMatchOptions& options) {
  ImageMatches matches;
  if (frame.keypoints.empty() || render.keypoints.size() < 2) return matches;
  EPILOC_CHECK(frame.descriptors.type() == render.descriptors.type(),
               "MatchFeatures: descriptors of different types");
  const int norm_type = NormType(frame.descriptors);
  if (options.search_radius_px > 0) {
    const KeypointGrid grid(render.keypoints, options.search_radius_px);
    for (size_t i = 0; i < frame.keypoints.size(); ++i) {
      const std::vector<int> near = grid.Near(frame.keypoints[i].pt);
      if (near.empty()) continue;
      const Nearest n =
          FindNearest(frame.descriptors.row(static_cast<int>(i)), render.descriptors, near,
                      norm_type);
      if (n.index >= 0 && n.best < options.ratio * n.second) {
        matches.frame_index.push_back(static_cast<int>(i));
        matches.render_index.push_back(n.index);
      }
    }
  } else {
    cv::BFMatcher matcher(norm_type);
    std::vector<std::vector<cv::DMatch>> knn;
    matcher.knnMatch(frame.descriptors, render.descriptors, knn, 2);
    for (const auto& m : knn) {
      if (m.size() < 2 || m[0].distance >= options.ratio * m[1].distance) continue;
      matches.frame_index.push_back(m[0].queryIdx);
      matches.render_index.push_back(m[0].trainIdx);
    }
  }
  // A render feature claimed by several frame features is ambiguous: keep none of them.
  std::vector<int> claims(render.keypoints.size(), 0);
  for (const int j : matches.render_index) ++claims[j];
  ImageMatches unique;
  for (size_t k = 0; k < matches.frame_index.size(); ++k) {
    if (claims[matches.render_index[k]] != 1) continue;
    unique.frame_index.push_back(matches.frame_index[k]);
    unique.render_index.push_back(matches.render_index[k]);
  }
  unique.num_ratio = static_cast<int>(unique.frame_index.size());
  unique.num_geometric = unique.num_ratio;
  if (options.fundamental_threshold_px <= 0 || unique.num_ratio < kMinMatchesForFundamental) {
    return unique;
  }
  std::vector<cv::Point2f> a, b;
  for (size_t k = 0; k < unique.frame_index.size(); ++k) {
    a.push_back(frame.keypoints[unique.frame_index[k]].pt);
    b.push_back(render.keypoints[unique.render_index[k]].pt);
  }
  cv::Mat inliers;
  const cv::Mat f = cv::findFundamentalMat(a, b, cv::USAC_MAGSAC,
                                           options.fundamental_threshold_px, 0.999, inliers);
  if (f.empty() || inliers.empty()) return unique;  // degenerate: leave it to PnP RANSAC
  ImageMatches kept;
  kept.num_ratio = unique.num_ratio;
  for (size_t k = 0; k < unique.frame_index.size(); ++k) {
    if (!inliers.at<uchar>(static_cast<int>(k))) continue;
    kept.frame_index.push_back(unique.frame_index[k]);
    kept.render_index.push_back(unique.render_index[k]);
  }
  kept.num_geometric = static_cast<int>(kept.frame_index.size());
  return kept;
}

}  // namespace epiloc
