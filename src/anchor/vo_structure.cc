// VoStructure: the VO poses and points structure anchoring registers (structure_anchor.h), read
// from `epiloc vo` files, other SLAM systems' trajectories and stella_vslam maps.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// "# segment K frames A..B ..." comments of an `epiloc vo` trajectory: (segment, first, last).
struct SegmentRange {
  int id = 0;
  frame_t first = kInvalidFrame;
  frame_t last = kInvalidFrame;
};

std::vector<SegmentRange> ReadSegmentComments(const std::string& path) {
  std::ifstream in(path);
  std::vector<SegmentRange> segments;
  std::string line;
  while (ReadLine(in, line, path, 0)) {
    if (line.empty() || line[0] != '#') continue;
    int id = 0;
    long long first = 0, last = 0;
    if (std::sscanf(line.c_str(), "# segment %d frames %lld..%lld", &id, &first, &last) == 3) {
      segments.push_back({id, static_cast<frame_t>(first), static_cast<frame_t>(last)});
    }
  }
  return segments;
}

}  // namespace

VoStructure VoStructure::Read(const std::string& trajectory_path, const std::string& points_path) {
  VoStructure vo;
  vo.poses = ReadTumPoses(trajectory_path);
  if (vo.poses.empty()) Throw("{}: the trajectory has no poses", trajectory_path);
  const std::string points = points_path.empty() ? VoPointsPath(trajectory_path) : points_path;
  if (!std::filesystem::exists(points)) {
    Throw("{}: no VO points file (epiloc vo writes it beside the trajectory; or give --vo-points)",
          points);
  }
  vo.points = ReadVoPoints(points);
  vo.segments.clear();
  for (const SegmentRange& s : ReadSegmentComments(trajectory_path)) {
    vo.segments.push_back({s.id, s.first, s.last});
  }
  return vo;
}

VoStructure VoStructure::FromPoses(std::vector<StampedPose> poses,
                                   const std::string& trajectory_path,
                                   const std::string& points_path) {
  VoStructure vo;
  vo.poses = std::move(poses);
  if (vo.poses.empty()) Throw("{}: the trajectory has no poses", trajectory_path);
  if (!points_path.empty()) vo.points = ReadVoPoints(points_path);
  for (const SegmentRange& s : ReadSegmentComments(trajectory_path)) {
    vo.segments.push_back({s.id, s.first, s.last});
  }
  return vo;
}

VoStructure VoStructure::FromStellaMap(const StellaMap& map,
                                       std::vector<StampedPose> poses,
                                       const std::string& path) {
  EPILOC_CHECK(poses.size() == map.keyframes.size(), "{}: {} poses for the map's {} keyframes",
               path, poses.size(), map.keyframes.size());
  VoStructure vo;
  vo.poses = std::move(poses);
  for (const StellaLandmark& landmark : map.landmarks) {
    int first = -1, last = -1, observations = 0;
    for (const int k : landmark.keyframes) {
      if (vo.poses[k].frame == kInvalidFrame) continue;
      if (first < 0) first = k;
      last = k;
      ++observations;
    }
    if (observations < 2) continue;
    VoPoint point;
    point.point_in_world = landmark.position_in_world;
    point.first_frame = vo.poses[first].frame;
    point.last_frame = vo.poses[last].frame;
    point.observations = observations;
    point.parallax_deg =
        ParallaxDeg(landmark.position_in_world, vo.poses[first].world_from_cam.translation,
                    vo.poses[last].world_from_cam.translation);
    vo.points.push_back(point);
  }
  // In first-frame order, as `epiloc vo` writes them.
  std::stable_sort(vo.points.begin(), vo.points.end(), [](const VoPoint& a, const VoPoint& b) {
    return a.first_frame < b.first_frame;
  });
  return vo;
}

VoStructure VoStructure::FromResult(const VoResult& result) {
  VoStructure vo;
  for (const VoFramePose& p : result.poses) {
    StampedPose pose;
    pose.timestamp_s = p.timestamp_s;
    pose.frame = p.frame;
    pose.world_from_cam = p.world_from_cam;
    vo.poses.push_back(pose);
  }
  vo.points = result.points;
  for (const VoSegment& s : result.segments)
    vo.segments.push_back({s.id, s.first_frame, s.last_frame});
  return vo;
}

int VoStructure::SegmentOf(frame_t frame) const {
  if (frame == kInvalidFrame) return -1;
  if (segments.empty()) return 0;
  for (const Segment& s : segments) {
    if (frame >= s.first && frame <= s.last) return s.id;
  }
  return -1;
}

VoStructure VoStructure::OnFramesOf(const Drive& drive, std::vector<int>* pose_of) const {
  VoStructure out = *this;
  std::vector<int> index(drive.frames.size(), -1);
  size_t j = 0;
  for (size_t i = 0; i < drive.frames.size(); ++i) {
    const double t = drive.frames[i].timestamp_s;
    while (j < poses.size() && poses[j].timestamp_s < t - 1e-3) ++j;
    if (j < poses.size() && std::abs(poses[j].timestamp_s - t) <= 1e-3) {
      index[i] = static_cast<int>(j);
      out.poses[j].frame = drive.frames[i].frame;
    }
  }
  if (pose_of) *pose_of = std::move(index);
  return out;
}

}  // namespace epiloc
