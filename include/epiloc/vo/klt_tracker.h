// Sparse feature tracks across consecutive frames: Shi-Tomasi corners spread over a grid, followed
// by pyramidal Lucas-Kanade optical flow with a forward-backward check (OpenCV). The tracker of
// the visual odometry (vo.h): fast enough for 1242x375 frames at well over 10 frames/s.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace epiloc {

// Identifier of one feature track; unique over the life of a tracker.
using track_t = int64_t;
constexpr track_t kInvalidTrack = -1;

struct KltOptions {
  int max_features = 1500;  // features kept per frame; Detect() tops up to this many
  int grid_cols = 16;       // detection grid (features are spread evenly over its cells)
  int grid_rows = 6;
  double min_distance_px = 10.0;  // between two features
  double quality_level = 0.001;   // Shi-Tomasi response relative to the image's best corner
  int window_px = 21;             // side of the Lucas-Kanade window, pixels (odd)
  int pyramid_levels = 3;         // pyramid levels above full resolution
  double max_fb_error_px = 1.0;   // forward-backward error above which a track is dropped
  int border_px = 6;              // features closer than this to the image border are dropped

  // Throws Error naming the first invalid field.
  void Check() const;
};

// A feature in the current frame: its track and its pixel position (distorted image coordinates,
// the centre of the top-left pixel at (0, 0)).
struct TrackedFeature {
  track_t id = kInvalidTrack;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct KltTrackStats {
  int tracked = 0;          // features followed into the new frame
  int lost = 0;             // features dropped (flow failed, forward-backward error, border)
  int used_prediction = 0;  // features whose search started at a predicted position
};

class KltTracker {
 public:
  explicit KltTracker(const KltOptions& options);

  // Follows the current features into `image` (CV_8UC1, same size every call), which becomes the
  // current frame. `predicted_pixels` optionally gives where a track is expected (e.g. its 3-D
  // point projected with a predicted pose): the search starts there, and from the previous
  // position if that fails. The first call only stores the image.
  KltTrackStats Track(const cv::Mat& image,
                      const std::unordered_map<track_t, Eigen::Vector2d>& predicted_pixels = {});

  // Detects corners in the current image away from the current features and starts new tracks,
  // up to KltOptions::max_features. Returns the number of tracks started.
  int Detect();

  // Ends the given tracks (e.g. outliers of the pose estimate).
  void Drop(const std::vector<track_t>& ids);
  // Ends every track (the current image stays, so Detect() can start new ones); ids keep
  // increasing.
  void Reset();

  const std::vector<TrackedFeature>& features() const { return features_; }
  bool has_image() const { return !pyramid_.empty(); }

 private:
  KltOptions options_;
  std::vector<cv::Mat> pyramid_;  // of the current image (with derivatives)
  cv::Mat image_;
  std::vector<TrackedFeature> features_;
  track_t next_id_ = 0;
};

}  // namespace epiloc
