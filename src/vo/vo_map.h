// The odometry's map (private to the vo module): keyframes with their observations, feature
// tracks with their 3-D points, triangulation and the local bundle adjustment.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "epiloc/core/types.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/vo/bundle_adjustment.h"
#include "epiloc/vo/klt_tracker.h"

namespace epiloc {

using keyframe_t = int64_t;  // index into VoMap::keyframes()
constexpr keyframe_t kInvalidKeyframe = -1;

struct Keyframe {
  keyframe_t id = kInvalidKeyframe;
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  int segment = 0;
  Rigid3d cam_from_world;
  // Tracks seen (normalised coordinates); cleared once the keyframe is far behind the window.
  std::vector<std::pair<track_t, Eigen::Vector2d>> observations;
  int tracked_points = 0;     // map points tracked when it was made
  double median_depth = 1.0;  // of its map points, world units
};

struct MapTrack {
  std::vector<std::pair<keyframe_t, Eigen::Vector2d>> observations;  // in keyframe order
  bool has_point = false;
  Eigen::Vector3d point_in_world = Eigen::Vector3d::Zero();
};

struct MapOptions {
  double max_error_px = 1.5;
  double min_parallax_deg = 1.0;
  int ba_window = 8;
  BundleOptions bundle;
  bool keep_history = false;  // keep pruned tracks with points for GlobalBundle
};

// Figures of a local or global bundle adjustment.
struct LocalBundleStats {
  int poses = 0;
  int fixed_poses = 0;
  int points = 0;
  int observations = 0;
  int removed_observations = 0;  // outliers after the adjustment
  double seconds = 0.0;
};

class VoMap {
 public:
  explicit VoMap(const MapOptions& options) : options_(options) {}

  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  Keyframe& keyframe(keyframe_t id) { return keyframes_[static_cast<size_t>(id)]; }
  const Keyframe& keyframe(keyframe_t id) const { return keyframes_[static_cast<size_t>(id)]; }
  std::unordered_map<track_t, MapTrack>& tracks() { return tracks_; }
  const MapTrack* FindTrack(track_t id) const;

  // Appends a keyframe and records its observations in the tracks (creating tracks).
  keyframe_t AddKeyframe(Keyframe keyframe);
  // Adds one observation to keyframe `id` and its track.
  void AddObservation(keyframe_t id, track_t track, const Eigen::Vector2d& x);

  // Triangulates tracks seen by keyframe `id` that have no point yet, from their first keyframe
  // in the same segment; returns the number of new points.
  int TriangulateNew(keyframe_t id);

  // Bundle adjustment of the last `ba_window` keyframes of `segment` and their points, with the
  // other keyframes seeing those points fixed; at least two poses (or the segment's first) are
  // held fixed. Observations with an error above max_error_px afterwards are removed.
  LocalBundleStats LocalBundle(int segment, keyframe_t segment_first);

  // Bundle adjustment of every keyframe of `segment` and every point they see (kept tracks
  // included, MapOptions::keep_history), `iterations` Levenberg-Marquardt iterations, twice: the
  // second time without the observations the first left above max_error_px. The gauge: the
  // segment's first keyframe is fixed and the scale by one translation coordinate of its second.
  LocalBundleStats GlobalBundle(int segment, keyframe_t segment_first, int iterations);

  // Median depth and number of points seen by keyframe `id`.
  std::pair<double, int> DepthStats(keyframe_t id) const;

  // Applies x' = scale * R * x + t to the points and keyframes (>= first) of a segment.
  void TransformSegment(keyframe_t first, double scale, const Rigid3d& similarity_rigid);

  // Every track with a 3-D point (current and kept ones), in no particular order.
  std::vector<const MapTrack*> PointTracks() const;

  // Forgets tracks (all of them: a new segment starts); kept ones stay for GlobalBundle.
  void ClearTracks();
  // Drops observations of keyframes far behind `newest` and tracks no longer needed (not alive
  // in the tracker and unseen by recent keyframes), bounding the memory of long drives.
  void Prune(keyframe_t newest, const std::vector<TrackedFeature>& alive);

 private:
  void Keep(MapTrack&& track);  // into kept_tracks_ if keep_history and useful

  MapOptions options_;
  std::vector<Keyframe> keyframes_;
  std::unordered_map<track_t, MapTrack> tracks_;
  std::vector<MapTrack> kept_tracks_;  // pruned or cleared tracks with points (keep_history)
};

}  // namespace epiloc
