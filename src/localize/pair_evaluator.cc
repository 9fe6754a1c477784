#include "epiloc/localize/pair_evaluator.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <numeric>
#include <thread>

#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"

namespace epiloc {

void PairOptions::Check() const {
  EPILOC_CHECK(max_db_features >= 0, "localize: max_db_features must be >= 0");
  EPILOC_CHECK(min_db_feature_angle_rad >= 0, "localize: min_db_feature_angle_rad must be >= 0");
  EPILOC_CHECK(cache_frames >= 1, "localize: cache_frames must be >= 1");
  EPILOC_CHECK(window_checks >= 1, "localize: window_checks must be >= 1, got {}", window_checks);
  match.Check();
  window.Check();
  epipole.Check();
}

PairEvaluator::PairEvaluator(const Database& db,
                             std::vector<DbFrame> frames,
                             const PairOptions& options)
    : db_(db), frames_(std::move(frames)), options_(options), window_matcher_(options.window) {
  options_.Check();
  for (const DbDrive& drive : db.ReadDrives()) {
    drive_cameras_[drive.drive_id] = drive.camera_id;
    if (cameras_.count(drive.camera_id) == 0) {
      cameras_[drive.camera_id] = db.ReadCamera(drive.camera_id).camera;
    }
  }
}

const Camera& PairEvaluator::DbCamera(int db_index) const {
  return cameras_.at(drive_cameras_.at(frames_.at(db_index).drive_id));
}

std::shared_ptr<const PairEvaluator::CachedFrame> PairEvaluator::Load(int db_index) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = cache_.find(db_index);
  if (it != cache_.end()) {
    lru_.splice(lru_.begin(), lru_, it->second.second);
    return it->second.first;
  }
  auto frame = std::make_shared<CachedFrame>();
  const image_t image_id = frames_[db_index].image_id;
  frame->keypoints = db_.ReadKeypoints(image_id);
  frame->descriptors = db_.ReadDescriptors(image_id);
  std::vector<DbFramePoint> points;
  if (options_.with_points) {
    points = db_.ReadFramePoints(image_id);
    auto map_points = std::make_shared<FrameMapPoints>();
    FeatureDescriptors observed(static_cast<int>(points.size()), 128);
    for (size_t k = 0; k < points.size(); ++k) {
      EPILOC_CHECK(points[k].feature_index < frame->descriptors.rows(),
                   "{}: image {} has a point observation of feature {} of {}", db_.path(), image_id,
                   points[k].feature_index, frame->descriptors.rows());
      observed.row(static_cast<int>(k)) = frame->descriptors.row(points[k].feature_index);
      map_points->point_id.push_back(points[k].point_id);
      map_points->point_in_enu.push_back(points[k].position_in_enu);
    }
    map_points->root_sift = ToRootSift(observed, static_cast<int>(points.size()));
    frame->map_points = std::move(map_points);
  }
  // Stored row of each kept row (the filter below moves rows up).
  std::vector<int> stored_row(frame->keypoints.rows());
  std::iota(stored_row.begin(), stored_row.end(), 0);
  if (options_.min_db_feature_angle_rad > 0) {
    // Drop the features too fine for the query, keeping the strongest-first order.
    const double min_size_px = options_.min_db_feature_angle_rad * DbCamera(db_index).fx;
    int kept = 0;
    for (int r = 0; r < frame->keypoints.rows(); ++r) {
      if (frame->keypoints(r, 2) < min_size_px) continue;
      if (kept != r) {
        frame->keypoints.row(kept) = frame->keypoints.row(r);
        frame->descriptors.row(kept) = frame->descriptors.row(r);
      }
      stored_row[kept] = r;
      ++kept;
    }
    frame->keypoints.conservativeResize(kept, Eigen::NoChange);
    frame->descriptors.conservativeResize(kept, Eigen::NoChange);
  }
  const int keep = options_.max_db_features > 0
                       ? std::min<int>(options_.max_db_features, frame->keypoints.rows())
                       : static_cast<int>(frame->keypoints.rows());
  // Rows are strongest first: the prefix is the best `keep` features.
  frame->keypoints.conservativeResize(keep, Eigen::NoChange);
  frame->descriptors.conservativeResize(keep, Eigen::NoChange);
  if (options_.with_points) {
    std::unordered_map<int, const DbFramePoint*> by_feature;
    for (const DbFramePoint& p : points) by_feature[p.feature_index] = &p;
    frame->point_id.assign(keep, -1);
    frame->point_in_enu.assign(keep, Eigen::Vector3d::Zero());
    for (int r = 0; r < keep; ++r) {
      const auto found = by_feature.find(stored_row[r]);
      if (found == by_feature.end()) continue;
      frame->point_id[r] = found->second->point_id;
      frame->point_in_enu[r] = found->second->position_in_enu;
    }
  }
  lru_.push_front(db_index);
  cache_[db_index] = {frame, lru_.begin()};
  while (static_cast<int>(cache_.size()) > options_.cache_frames) {
    cache_.erase(lru_.back());
    lru_.pop_back();
  }
  return frame;
}

std::shared_ptr<const FrameMapPoints> PairEvaluator::MapPoints(int db_index) const {
  EPILOC_CHECK(options_.with_points, "PairEvaluator::MapPoints: needs PairOptions::with_points");
  return Load(db_index)->map_points;
}

PairResult PairEvaluator::EpipoleOfMatches(const Camera& query_camera,
                                           const FeatureKeypoints& query_keypoints,
                                           int db_index,
                                           const CachedFrame& db_frame,
                                           const std::vector<std::pair<int, int>>& rows) const {
  std::vector<Eigen::Vector2d> query_points, db_points;
  query_points.reserve(rows.size());
  db_points.reserve(rows.size());
  for (const auto& [query_row, db_row] : rows) {
    query_points.emplace_back(query_keypoints(query_row, 0), query_keypoints(query_row, 1));
    db_points.emplace_back(db_frame.keypoints(db_row, 0), db_frame.keypoints(db_row, 1));
  }
  const Camera& db_camera = DbCamera(db_index);
  EpipoleResult epipole =
      EstimateEpipole(query_points, query_camera, db_points, db_camera, options_.epipole);
  if (!epipole.valid && options_.fundamental_fallback &&
      options_.epipole.model == EpipoleOptions::Model::kEssential &&
      epipole.num_matches >= options_.epipole.min_inliers) {
    EpipoleOptions fallback = options_.epipole;
    fallback.model = EpipoleOptions::Model::kFundamental;
    EpipoleResult second =
        EstimateEpipole(query_points, query_camera, db_points, db_camera, fallback);
    if (second.valid) epipole = std::move(second);
  }
  PairResult result;
  result.db_index = db_index;
  result.valid = epipole.valid;
  result.distance = epipole.distance;
  result.signed_distance = epipole.signed_distance;
  result.num_matches = epipole.num_matches;
  result.num_inliers = epipole.num_inliers;
  result.parallax_deg = epipole.median_parallax_deg;
  if (epipole.valid) {
    // The database camera's direction from the query, turned into the database camera's frame:
    // that camera looks along the route, so the query's own heading (a turn, a lane change)
    // drops out of the cotangent.
    const Eigen::Vector3d v = epipole.db_from_query * epipole.db_center_in_query;
    result.signed_cot = std::abs(v.x()) > 0 ? v.z() / std::abs(v.x()) : std::copysign(1e12, v.z());
    result.heading_deg =
        std::atan2(epipole.db_from_query(0, 2), epipole.db_from_query(2, 2)) * 180.0 / M_PI;
  }
  result.failure = epipole.failure;
  if (options_.with_points) {
    for (const auto& [query_row, db_row] : rows) {
      if (db_frame.point_id[db_row] < 0) continue;
      result.point_matches.push_back(
          {query_row, db_frame.point_id[db_row], db_frame.point_in_enu[db_row]});
    }
  }
  return result;
}

PairResult PairEvaluator::EvaluateOne(const Camera& query_camera,
                                      const FeatureKeypoints& query_keypoints,
                                      const DescriptorIndex& query_index,
                                      int db_index) const {
  const std::shared_ptr<const CachedFrame> db_frame = Load(db_index);
  std::vector<std::pair<int, int>> rows;
  for (const FeatureMatch& m : query_index.Match(db_frame->descriptors)) {
    rows.emplace_back(m.index_a, m.index_b);
  }
  return EpipoleOfMatches(query_camera, query_keypoints, db_index, *db_frame, rows);
}

std::vector<PairResult> PairEvaluator::Evaluate(const Camera& query_camera,
                                                const FeatureKeypoints& query_keypoints,
                                                const DescriptorIndex& query_index,
                                                const std::vector<int>& db_indices,
                                                int num_threads) const {
  std::vector<PairResult> results(db_indices.size());
  ParallelFor(static_cast<int64_t>(db_indices.size()), num_threads, [&](int64_t k) {
    results[k] = EvaluateOne(query_camera, query_keypoints, query_index, db_indices[k]);
  });
  return results;
}

std::vector<PairResult> PairEvaluator::EvaluateWindow(const Camera& query_camera,
                                                      const FeatureSet& query,
                                                      const std::vector<int>& db_indices,
                                                      int num_threads,
                                                      double* match_seconds,
                                                      double* geometry_seconds,
                                                      double* window_seconds) {
  if (db_indices.empty()) return {};
  using Clock = std::chrono::steady_clock;
  const Clock::time_point window_start = Clock::now();
  Maintain();
  window_matcher_.SetWindow(db_indices, [this](int db_index) {
    const std::shared_ptr<const CachedFrame> frame = Load(db_index);
    // Aliasing pointer: keeps the cached frame alive while the matcher holds its descriptors.
    return std::shared_ptr<const FeatureDescriptors>(frame, &frame->descriptors);
  });
  const Clock::time_point start = Clock::now();
  if (window_seconds) *window_seconds += std::chrono::duration<double>(start - window_start).count();
  const std::unordered_map<int, std::vector<WindowMatch>> matches = window_matcher_.Match(
      query.descriptors, -1, options_.match.ratio, options_.window_checks, num_threads);
  const Clock::time_point matched = Clock::now();
  std::vector<PairResult> results(db_indices.size());
  ParallelFor(static_cast<int64_t>(db_indices.size()), num_threads, [&](int64_t k) {
    const int db_index = db_indices[k];
    std::vector<std::pair<int, int>> rows;
    const auto it = matches.find(db_index);
    if (it != matches.end()) {
      for (const WindowMatch& m : it->second) rows.emplace_back(m.query_row, m.db_row);
    }
    results[k] = EpipoleOfMatches(query_camera, query.keypoints, db_index, *Load(db_index), rows);
  });
  if (match_seconds) *match_seconds += std::chrono::duration<double>(matched - start).count();
  if (geometry_seconds) {
    *geometry_seconds += std::chrono::duration<double>(Clock::now() - matched).count();
  }
  return results;
}

void PairEvaluator::Prefetch(const std::vector<int>& db_indices) const {
  for (const int db_index : db_indices) Load(db_index);
}

void PairEvaluator::Maintain() {
  if (window_matcher_.RebuildDue()) window_matcher_.Rebuild();
}

}  // namespace epiloc
