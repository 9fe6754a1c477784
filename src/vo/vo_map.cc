#include "vo_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_set>

#include "epiloc/vo/two_view.h"

namespace epiloc {

const MapTrack* VoMap::FindTrack(track_t id) const {
  const auto it = tracks_.find(id);
  return it == tracks_.end() ? nullptr : &it->second;
}

keyframe_t VoMap::AddKeyframe(Keyframe keyframe) {
  keyframe.id = static_cast<keyframe_t>(keyframes_.size());
  for (const auto& [track, x] : keyframe.observations) {
    tracks_[track].observations.emplace_back(keyframe.id, x);
  }
  keyframes_.push_back(std::move(keyframe));
  return keyframes_.back().id;
}

void VoMap::AddObservation(keyframe_t id, track_t track, const Eigen::Vector2d& x) {
  keyframe(id).observations.emplace_back(track, x);
  tracks_[track].observations.emplace_back(id, x);
}

int VoMap::TriangulateNew(keyframe_t id) {
  const Keyframe& kf = keyframe(id);
  const double max_error2 = std::pow(options_.max_error_px / options_.bundle.focal_px, 2);
  int added = 0;
  for (const auto& [track_id, x] : kf.observations) {
    auto it = tracks_.find(track_id);
    if (it == tracks_.end()) continue;
    MapTrack& track = it->second;
    if (track.has_point || track.observations.size() < 2) continue;
    // The first keyframe that saw the track gives the longest baseline.
    const auto& [first_id, first_x] = track.observations.front();
    if (first_id == id) continue;
    const Keyframe& first = keyframe(first_id);
    if (first.segment != kf.segment) continue;
    const auto point = TriangulatePoint(first.cam_from_world, kf.cam_from_world, first_x, x);
    if (!point) continue;
    if (SquaredReprojectionError(first.cam_from_world, *point, first_x) > max_error2 ||
        SquaredReprojectionError(kf.cam_from_world, *point, x) > max_error2) {
      continue;
    }
    if (ParallaxDeg(first.cam_from_world, kf.cam_from_world, *point) < options_.min_parallax_deg) {
      continue;  // stays a candidate: the baseline grows with the next keyframes
    }
    track.point_in_world = *point;
    track.has_point = true;
    ++added;
  }
  return added;
}

LocalBundleStats VoMap::LocalBundle(int segment, keyframe_t segment_first) {
  const auto start = std::chrono::steady_clock::now();
  LocalBundleStats stats;
  if (keyframes_.empty()) return stats;
  const keyframe_t newest = static_cast<keyframe_t>(keyframes_.size()) - 1;
  const keyframe_t window_first = std::max(segment_first, newest - options_.ba_window + 1);

  BundleProblem problem;
  std::unordered_map<keyframe_t, int> pose_index;
  std::vector<keyframe_t> pose_ids;
  const auto add_pose = [&](keyframe_t id, bool fixed) {
    pose_index[id] = static_cast<int>(pose_ids.size());
    pose_ids.push_back(id);
    problem.cam_from_world.push_back(keyframe(id).cam_from_world);
    problem.pose_fixed.push_back(fixed);
  };
  for (keyframe_t id = window_first; id <= newest; ++id) add_pose(id, false);

  std::vector<track_t> point_ids;
  std::unordered_set<track_t> seen;
  for (keyframe_t id = window_first; id <= newest; ++id) {
    for (const auto& [track_id, x] : keyframe(id).observations) {
      const auto it = tracks_.find(track_id);
      if (it == tracks_.end() || !it->second.has_point || !seen.insert(track_id).second) continue;
      point_ids.push_back(track_id);
    }
  }
  int fixed = 0;
  for (size_t p = 0; p < point_ids.size(); ++p) {
    const MapTrack& track = tracks_.at(point_ids[p]);
    problem.points_in_world.push_back(track.point_in_world);
    for (const auto& [kf_id, x] : track.observations) {
      if (keyframe(kf_id).segment != segment) continue;
      if (!pose_index.count(kf_id)) {
        add_pose(kf_id, true);
        ++fixed;
      }
      problem.observations.push_back({pose_index.at(kf_id), static_cast<int>(p), x});
    }
  }
  // Gauge of a monocular map: position, orientation and scale need two fixed poses (at the start
  // of a segment only its first keyframe is fixed; the scale is then set by the caller).
  if (window_first == segment_first) {
    problem.pose_fixed[0] = true;
    ++fixed;
  }
  const int num_window = static_cast<int>(newest - window_first + 1);
  for (int i = 0; i < num_window && fixed < 2 && num_window - i > 1; ++i) {
    if (!problem.pose_fixed[i]) {
      problem.pose_fixed[i] = true;
      ++fixed;
    }
  }
  stats.poses = static_cast<int>(pose_ids.size());
  stats.fixed_poses = fixed;
  stats.points = static_cast<int>(point_ids.size());
  stats.observations = static_cast<int>(problem.observations.size());
  if (problem.observations.empty()) return stats;

  SolveBundle(problem, options_.bundle);

  for (size_t i = 0; i < pose_ids.size(); ++i) {
    if (!problem.pose_fixed[i]) keyframe(pose_ids[i]).cam_from_world = problem.cam_from_world[i];
  }
  const double max_error2 = std::pow(options_.max_error_px / options_.bundle.focal_px, 2);
  std::vector<std::vector<keyframe_t>> outliers(point_ids.size());
  for (const BundleObservation& o : problem.observations) {
    if (SquaredReprojectionError(problem.cam_from_world[o.pose], problem.points_in_world[o.point],
                                 o.x) > max_error2) {
      outliers[o.point].push_back(pose_ids[o.pose]);
    }
  }
  for (size_t p = 0; p < point_ids.size(); ++p) {
    MapTrack& track = tracks_.at(point_ids[p]);
    track.point_in_world = problem.points_in_world[p];
    if (outliers[p].empty()) continue;
    stats.removed_observations += static_cast<int>(outliers[p].size());
    auto& obs = track.observations;
    obs.erase(std::remove_if(obs.begin(), obs.end(),
                             [&](const std::pair<keyframe_t, Eigen::Vector2d>& o) {
                               return std::find(outliers[p].begin(), outliers[p].end(), o.first) !=
                                      outliers[p].end();
                             }),
              obs.end());
    if (obs.size() < 2) track.has_point = false;
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

LocalBundleStats VoMap::GlobalBundle(int segment, keyframe_t segment_first, int iterations) {
  const auto start = std::chrono::steady_clock::now();
  LocalBundleStats stats;
  keyframe_t last = segment_first;
  while (last + 1 < static_cast<keyframe_t>(keyframes_.size()) &&
         keyframe(last + 1).segment == segment) {
    ++last;
  }
  if (last - segment_first < 2) return stats;  // nothing the local BA did not already see

  const auto in_segment = [&](keyframe_t id) { return id >= segment_first && id <= last; };
  std::vector<MapTrack*> tracks;
  const auto collect = [&](MapTrack& track) {
    int seen = 0;
    for (const auto& o : track.observations) seen += in_segment(o.first) ? 1 : 0;
    if (seen >= 2) {
      tracks.push_back(&track);
    } else if (seen > 0) {
      track.has_point = false;  // its outliers removed, one view cannot hold a point
    }
  };

  BundleProblem problem;
  for (keyframe_t id = segment_first; id <= last; ++id) {
    problem.cam_from_world.push_back(keyframe(id).cam_from_world);
    problem.pose_fixed.push_back(id == segment_first);
  }
  // The scale: the second keyframe's largest translation coordinate (its baseline to the first).
  problem.scale_pose = 1;
  problem.cam_from_world[1].translation.cwiseAbs().maxCoeff(&problem.scale_axis);
  BundleOptions options = options_.bundle;
  options.max_iterations = iterations;
  const double max_error2 = std::pow(options_.max_error_px / options_.bundle.focal_px, 2);
  for (int round = 0; round < 2; ++round) {
    tracks.clear();
    for (auto& [id, track] : tracks_) {
      if (track.has_point) collect(track);
    }
    for (MapTrack& track : kept_tracks_) {
      if (track.has_point) collect(track);
    }
    problem.points_in_world.clear();
    problem.observations.clear();
    for (size_t p = 0; p < tracks.size(); ++p) {
      problem.points_in_world.push_back(tracks[p]->point_in_world);
      for (const auto& [kf_id, x] : tracks[p]->observations) {
        if (!in_segment(kf_id)) continue;
        problem.observations.push_back(
            {static_cast<int>(kf_id - segment_first), static_cast<int>(p), x});
      }
    }
    SolveBundle(problem, options);
    for (size_t p = 0; p < tracks.size(); ++p) {
      tracks[p]->point_in_world = problem.points_in_world[p];
    }
    // Outliers of the adjusted map leave the second round.
    for (size_t p = 0; p < tracks.size(); ++p) {
      auto& obs = tracks[p]->observations;
      const size_t before = obs.size();
      obs.erase(std::remove_if(obs.begin(), obs.end(),
                               [&](const std::pair<keyframe_t, Eigen::Vector2d>& o) {
                                 return in_segment(o.first) &&
                                        SquaredReprojectionError(
                                            problem.cam_from_world[o.first - segment_first],
                                            tracks[p]->point_in_world, o.second) > max_error2;
                               }),
                obs.end());
      stats.removed_observations += static_cast<int>(before - obs.size());
    }
  }
  for (keyframe_t id = segment_first; id <= last; ++id) {
    Keyframe& kf = keyframe(id);
    kf.cam_from_world = problem.cam_from_world[static_cast<size_t>(id - segment_first)];
  }
  stats.poses = static_cast<int>(problem.cam_from_world.size());
  stats.fixed_poses = 1;
  stats.points = static_cast<int>(tracks.size());
  stats.observations = static_cast<int>(problem.observations.size());
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

std::pair<double, int> VoMap::DepthStats(keyframe_t id) const {
  const Keyframe& kf = keyframe(id);
  std::vector<double> depths;
  for (const auto& [track_id, x] : kf.observations) {
    const MapTrack* track = FindTrack(track_id);
    if (!track || !track->has_point) continue;
    const double z = (kf.cam_from_world * track->point_in_world).z();
    if (z > 0.0) depths.push_back(z);
  }
  if (depths.empty()) return {1.0, 0};
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  return {depths[depths.size() / 2], static_cast<int>(depths.size())};
}

void VoMap::TransformSegment(keyframe_t first, double scale, const Rigid3d& similarity_rigid) {
  const Eigen::Quaterniond& r = similarity_rigid.rotation;
  const Eigen::Vector3d& t = similarity_rigid.translation;
  for (size_t i = static_cast<size_t>(first); i < keyframes_.size(); ++i) {
    // x_cam = Rc * x + tc with x = R^T (x' - t) / scale; the camera frame scales too.
    Rigid3d& pose = keyframes_[i].cam_from_world;
    const Eigen::Quaterniond rc = pose.rotation * r.conjugate();
    pose.translation = scale * pose.translation - rc * t;
    pose.rotation = rc;
    keyframes_[i].median_depth *= scale;
  }
  for (auto& [id, track] : tracks_) {
    if (track.has_point) track.point_in_world = scale * (r * track.point_in_world) + t;
  }
}

std::vector<const MapTrack*> VoMap::PointTracks() const {
  std::vector<const MapTrack*> out;
  for (const auto& [id, track] : tracks_) {
    if (track.has_point && !track.observations.empty()) out.push_back(&track);
  }
  for (const MapTrack& track : kept_tracks_) {
    if (track.has_point && !track.observations.empty()) out.push_back(&track);
  }
  return out;
}

void VoMap::Keep(MapTrack&& track) {
  if (options_.keep_history && track.has_point && track.observations.size() >= 2) {
    kept_tracks_.push_back(std::move(track));
  }
}

void VoMap::ClearTracks() {
  for (auto& [id, track] : tracks_) Keep(std::move(track));
  tracks_.clear();
}

void VoMap::Prune(keyframe_t newest, const std::vector<TrackedFeature>& alive) {
  const keyframe_t keep_from = newest - 2 * options_.ba_window;
  if (keep_from > 0) {
    Keyframe& old = keyframe(keep_from - 1);
    old.observations.clear();
    old.observations.shrink_to_fit();
  }
  std::unordered_set<track_t> alive_ids;
  alive_ids.reserve(alive.size());
  for (const TrackedFeature& f : alive) alive_ids.insert(f.id);
  const keyframe_t window_first = newest - options_.ba_window + 1;
  for (auto it = tracks_.begin(); it != tracks_.end();) {
    const MapTrack& track = it->second;
    const bool recent =
        !track.observations.empty() && track.observations.back().first >= window_first;
    if (!recent && !alive_ids.count(it->first)) {
      Keep(std::move(it->second));
      it = tracks_.erase(it);
    } else {
      ++it;
    }
  }
}

}  // namespace epiloc
