#include "epiloc/vo/klt_tracker.h"

#include <algorithm>
#include <unordered_set>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

bool Inside(const cv::Point2f& p, const cv::Size& size, int border) {
  return p.x >= border && p.y >= border && p.x <= size.width - 1 - border &&
         p.y <= size.height - 1 - border;
}

}  // namespace

void KltOptions::Check() const {
  EPILOC_CHECK(max_features >= 8, "vo: max_features must be >= 8, got {}", max_features);
  EPILOC_CHECK(grid_cols >= 1 && grid_rows >= 1, "vo: the detection grid needs >= 1x1 cells");
  EPILOC_CHECK(min_distance_px > 0.0, "vo: min_distance_px must be > 0, got {}", min_distance_px);
  EPILOC_CHECK(quality_level > 0.0 && quality_level < 1.0,
               "vo: quality_level must be in (0, 1), got {}", quality_level);
  EPILOC_CHECK(window_px >= 5 && window_px % 2 == 1, "vo: window_px must be odd and >= 5, got {}",
               window_px);
  EPILOC_CHECK(pyramid_levels >= 0 && pyramid_levels <= 6,
               "vo: pyramid_levels must be in [0, 6], got {}", pyramid_levels);
  EPILOC_CHECK(max_fb_error_px > 0.0, "vo: max_fb_error_px must be > 0, got {}", max_fb_error_px);
  EPILOC_CHECK(border_px >= 0, "vo: border_px must be >= 0, got {}", border_px);
}

KltTracker::KltTracker(const KltOptions& options) : options_(options) { options_.Check(); }

KltTrackStats KltTracker::Track(
    const cv::Mat& image, const std::unordered_map<track_t, Eigen::Vector2d>& predicted_pixels) {
  EPILOC_CHECK(image.type() == CV_8UC1, "vo: the tracker needs 8-bit grey images");
  const cv::Size window(options_.window_px, options_.window_px);
  std::vector<cv::Mat> pyramid;
  cv::buildOpticalFlowPyramid(image, pyramid, window, options_.pyramid_levels, true);
  KltTrackStats stats;
  if (pyramid_.empty() || features_.empty()) {
    stats.lost = static_cast<int>(features_.size());
    features_.clear();
    pyramid_ = std::move(pyramid);
    image_ = image;
    return stats;
  }
  EPILOC_CHECK(image.size() == image_.size(), "vo: frame size changed from {}x{} to {}x{}",
               image_.cols, image_.rows, image.cols, image.rows);

  const size_t n = features_.size();
  std::vector<cv::Point2f> previous(n), current(n);
  std::vector<char> predicted(n, 0);
  for (size_t i = 0; i < n; ++i) {
    previous[i] = cv::Point2f(static_cast<float>(features_[i].pixel.x()),
                              static_cast<float>(features_[i].pixel.y()));
    current[i] = previous[i];
    const auto it = predicted_pixels.find(features_[i].id);
    if (it != predicted_pixels.end()) {
      const cv::Point2f p(static_cast<float>(it->second.x()), static_cast<float>(it->second.y()));
      if (Inside(p, image.size(), 0)) {
        current[i] = p;
        predicted[i] = 1;
      }
    }
  }
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  std::vector<uchar> status, back_status;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(pyramid_, pyramid, previous, current, status, error, window,
                           options_.pyramid_levels, criteria, cv::OPTFLOW_USE_INITIAL_FLOW);

  // A prediction can be wrong (a bad pose): search again from the previous position.
  std::vector<size_t> retry;
  for (size_t i = 0; i < n; ++i) {
    if (predicted[i] && !status[i]) retry.push_back(i);
  }
  if (!retry.empty()) {
    std::vector<cv::Point2f> from(retry.size()), to(retry.size());
    for (size_t k = 0; k < retry.size(); ++k) from[k] = to[k] = previous[retry[k]];
    std::vector<uchar> retry_status;
    std::vector<float> retry_error;
    cv::calcOpticalFlowPyrLK(pyramid_, pyramid, from, to, retry_status, retry_error, window,
                             options_.pyramid_levels, criteria, cv::OPTFLOW_USE_INITIAL_FLOW);
    for (size_t k = 0; k < retry.size(); ++k) {
      status[retry[k]] = retry_status[k];
      current[retry[k]] = to[k];
      predicted[retry[k]] = 0;
    }
  }

  // Forward-backward check: track the new positions back and compare.
  std::vector<cv::Point2f> back = previous;
  cv::calcOpticalFlowPyrLK(pyramid, pyramid_, current, back, back_status, error, window,
                           options_.pyramid_levels, criteria, cv::OPTFLOW_USE_INITIAL_FLOW);
  const double max_fb2 = options_.max_fb_error_px * options_.max_fb_error_px;
  std::vector<TrackedFeature> kept;
  kept.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2f d = back[i] - previous[i];
    if (!status[i] || !back_status[i] || d.dot(d) > max_fb2 ||
        !Inside(current[i], image.size(), options_.border_px)) {
      ++stats.lost;
      continue;
    }
    kept.push_back({features_[i].id, Eigen::Vector2d(current[i].x, current[i].y)});
    ++stats.tracked;
    stats.used_prediction += predicted[i];
  }
  features_ = std::move(kept);
  pyramid_ = std::move(pyramid);
  image_ = image;
  return stats;
}

int KltTracker::Detect() {
  if (image_.empty()) return 0;
  const int wanted = options_.max_features - static_cast<int>(features_.size());
  if (wanted <= 0) return 0;
  const cv::Size size = image_.size();
  cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
  const int b = options_.border_px;
  mask(cv::Rect(b, b, std::max(1, size.width - 2 * b), std::max(1, size.height - 2 * b)))
      .setTo(255);
  const int radius = static_cast<int>(std::ceil(options_.min_distance_px));
  const int cols = options_.grid_cols, rows = options_.grid_rows;
  const auto cell_of = [&](float x, float y) {
    const int cx = std::clamp(static_cast<int>(x * cols / size.width), 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(y * rows / size.height), 0, rows - 1);
    return cy * cols + cx;
  };
  std::vector<int> per_cell(static_cast<size_t>(cols * rows), 0);
  for (const TrackedFeature& f : features_) {
    cv::circle(mask, cv::Point(cvRound(f.pixel.x()), cvRound(f.pixel.y())), radius, 0, -1);
    ++per_cell[cell_of(static_cast<float>(f.pixel.x()), static_cast<float>(f.pixel.y()))];
  }
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(image_, corners, 4 * options_.max_features, options_.quality_level,
                          options_.min_distance_px, mask, 3, false);
  // Corners come strongest first: fill every cell up to its share, then the rest by strength.
  const int quota = (options_.max_features + cols * rows - 1) / (cols * rows);
  std::vector<char> taken(corners.size(), 0);
  int added = 0;
  for (int pass = 0; pass < 2 && added < wanted; ++pass) {
    for (size_t i = 0; i < corners.size() && added < wanted; ++i) {
      if (taken[i]) continue;
      const int cell = cell_of(corners[i].x, corners[i].y);
      if (pass == 0 && per_cell[cell] >= quota) continue;
      taken[i] = 1;
      ++per_cell[cell];
      features_.push_back({next_id_++, Eigen::Vector2d(corners[i].x, corners[i].y)});
      ++added;
    }
  }
  return added;
}

void KltTracker::Drop(const std::vector<track_t>& ids) {
  if (ids.empty()) return;
  const std::unordered_set<track_t> drop(ids.begin(), ids.end());
  features_.erase(std::remove_if(features_.begin(), features_.end(),
                                 [&](const TrackedFeature& f) { return drop.count(f.id) > 0; }),
                  features_.end());
}

void KltTracker::Reset() { features_.clear(); }

}  // namespace epiloc
