// The epipolar distance between one query frame and database frames: features of the database
// frames are streamed from SQLite through a bounded cache (memory independent of route length),
// matched against the query frame's FLANN index and turned into an epipole (Kyutoku et al.).
#pragma once

#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "epiloc/camera/camera.h"
#include "epiloc/core/types.h"
#include "epiloc/db/database.h"
#include "epiloc/feature/matcher.h"
#include "epiloc/geometry/epipole.h"
#include "epiloc/localize/window_matcher.h"

namespace epiloc {

struct PairOptions {
  // Strongest database features used per frame (prefix of the stored rows; 0 = all).
  int max_db_features = 2000;
  // Database features whose SIFT scale, as an angle (keypoint size / fx, radians), is below this
  // are skipped before the strongest max_db_features are taken: features finer than the query
  // extraction can detect cannot match, and would crowd out those that can (0 = keep all).
  double min_db_feature_angle_rad = 0.0;
  // Database frames kept in memory; older ones are reloaded from SQLite when needed again.
  int cache_frames = 96;
  MatchOptions match;
  EpipoleOptions epipole;
  // Match each query frame once against all database frames of its window (one FLANN index over
  // the window, WindowMatcher) instead of once per pair: ~4x faster.
  bool window_matching = true;
  WindowMatcherOptions window;
  // Distances computed per query descriptor over the window (the window's trees have leaves of
  // window.leaf_size points: 128 over leaves of 8 recall about what 64 did over single points,
  // in half the time; match.num_checks is the per-pair matcher's).
  int window_checks = 128;
  // Also report, per pair, the matches whose database feature sees a triangulated 3-D point
  // (PairResult::point_matches, for the 6-DoF refinement); needs a database with structure.
  bool with_points = false;
  // Retry a pair with the 8-point fundamental matrix when the essential matrix fails (USAC
  // occasionally locks onto a wrong model for near-identical viewpoints).
  bool fundamental_fallback = true;

  void Check() const;
};

// A query feature matched to a database feature that sees a triangulated point.
struct PointMatch {
  int query_row = -1;
  int64_t point_id = -1;
  Eigen::Vector3d point_in_enu = Eigen::Vector3d::Zero();
};

// The 3-D points one database frame sees, each with the RootSIFT descriptor of the feature that
// sees it (every observed feature, not only the matched prefix): the local map the refinement
// searches by projection.
struct FrameMapPoints {
  std::vector<int64_t> point_id;
  std::vector<Eigen::Vector3d> point_in_enu;
  std::vector<float> root_sift;  // 128 per point
  int size() const { return static_cast<int>(point_id.size()); }
};

// What one query/database pair gave.
struct PairResult {
  int db_index = -1;  // index into the evaluator's database frame list
  bool valid = false;
  double distance = 0.0;         // d = 1/|e_x|, 1/pixels of the query image
  double signed_distance = 0.0;  // d with the sign of q_z (database camera ahead = positive)
  int num_matches = 0;
  int num_inliers = 0;
  double parallax_deg = 0.0;  // median rotation-compensated angle between matched rays
  // v_z / |v_x| for v the database camera centre's direction from the query, in the database
  // camera's frame (x right, z forward along the route): the signed cotangent of the baseline
  // with the query's heading cancelled (f * signed_distance when the two cameras are parallel).
  double signed_cot = 0.0;
  // Yaw of the query camera relative to the database camera, degrees (+ = turned right).
  double heading_deg = 0.0;
  std::string failure;
  std::vector<PointMatch> point_matches;  // with PairOptions::with_points (all ratio-test matches)
};

class PairEvaluator {
 public:
  // `frames` are the database frames in route order (by s); `db` must outlive the evaluator and
  // is read from the calling thread only (loads happen inside Evaluate under a lock).
  PairEvaluator(const Database& db, std::vector<DbFrame> frames, const PairOptions& options);

  const std::vector<DbFrame>& frames() const { return frames_; }
  const Camera& DbCamera(int db_index) const;

  // Evaluates the query frame (its undistorted pinhole camera, keypoints and FLANN index)
  // against each listed database frame, in parallel over `num_threads`.
  std::vector<PairResult> Evaluate(const Camera& query_camera,
                                   const FeatureKeypoints& query_keypoints,
                                   const DescriptorIndex& query_index,
                                   const std::vector<int>& db_indices,
                                   int num_threads) const;

  // With options.with_points: the points database frame `db_index` sees (loaded and cached
  // with its features). Thread-safe.
  std::shared_ptr<const FrameMapPoints> MapPoints(int db_index) const;

  // The same with one search of the query's descriptors against the window of `db_indices`
  // (WindowMatcher); the window slides incrementally between calls. Not thread-safe.
  // `window_seconds` (database frames loaded, the window's index updated), `match_seconds` and
  // `geometry_seconds`, when given, get the wall time of the three stages added. With
  // options.window.defer_rebuilds, a rebuild of the window's index the last call left due is
  // done first (Maintain() does it earlier, between calls).
  std::vector<PairResult> EvaluateWindow(const Camera& query_camera,
                                         const FeatureSet& query,
                                         const std::vector<int>& db_indices,
                                         int num_threads,
                                         double* match_seconds = nullptr,
                                         double* geometry_seconds = nullptr,
                                         double* window_seconds = nullptr);

  // Whether the window's index is due for a rebuild (options.window.defer_rebuilds), and the
  // rebuild: upkeep for a streaming caller's idle time between frames. Not thread-safe.
  bool MaintenanceDue() const { return window_matcher_.RebuildDue(); }
  void Maintain();
  // Reads the listed database frames into the cache (those not there yet). Thread-safe.
  void Prefetch(const std::vector<int>& db_indices) const;

 private:
  struct CachedFrame {
    FeatureKeypoints keypoints;
    FeatureDescriptors descriptors;
    // With options.with_points: per kept row, the id (-1: none) and position of its 3-D point.
    std::vector<int64_t> point_id;
    std::vector<Eigen::Vector3d> point_in_enu;
    std::shared_ptr<const FrameMapPoints> map_points;  // all its observed points
  };
  std::shared_ptr<const CachedFrame> Load(int db_index) const;
  PairResult EvaluateOne(const Camera& query_camera,
                         const FeatureKeypoints& query_keypoints,
                         const DescriptorIndex& query_index,
                         int db_index) const;
  // Epipole from matched rows (query row, database row) of one pair.
  PairResult EpipoleOfMatches(const Camera& query_camera,
                              const FeatureKeypoints& query_keypoints,
                              int db_index,
                              const CachedFrame& db_frame,
                              const std::vector<std::pair<int, int>>& rows) const;

  const Database& db_;
  std::vector<DbFrame> frames_;
  std::unordered_map<camera_t, Camera> cameras_;  // by drive's camera id
  std::unordered_map<drive_t, camera_t> drive_cameras_;
  PairOptions options_;
  WindowMatcher window_matcher_;
  mutable std::mutex mutex_;
  mutable std::list<int> lru_;  // most recent first
  mutable std::
      unordered_map<int, std::pair<std::shared_ptr<const CachedFrame>, std::list<int>::iterator>>
          cache_;
};

}  // namespace epiloc
