// stella_vslam's map database in its MessagePack format (`--map-db-out map.msg` with the
// `msgpack` map format): the keyframes' times and poses and the landmarks (3-D map points) with
// the keyframes that observe them. The root object holds "keyframes" and "landmarks", each an
// object keyed by id; a keyframe has "ts" (seconds), "rot_cw" (quaternion x, y, z, w of the
// camera-from-world rotation), "trans_cw" and "lm_ids" (per keypoint the id of its landmark, -1
// for none); a landmark has "pos_w" (world position). Other fields (descriptors, keypoints, the
// covisibility graph, cameras) are not read. The map is in stella's world frame and monocular
// units, as its trajectory files are.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/io/pose_files.h"

namespace epiloc {

struct StellaLandmark {
  int64_t id = 0;
  Eigen::Vector3d position_in_world = Eigen::Vector3d::Zero();
  std::vector<int> keyframes;  // indices into StellaMap::keyframes that observe it, increasing
};

struct StellaMap {
  // world_from_cam of each keyframe, in increasing time (frame = kInvalidFrame; line = 0).
  std::vector<StampedPose> keyframes;
  std::vector<int64_t> keyframe_ids;      // stella's id of each keyframe
  std::vector<StellaLandmark> landmarks;  // those observed by at least one keyframe, by id
};

// Whether `path` starts as a MessagePack map (the first byte of stella's map.msg) rather than
// text. False for a file that cannot be opened.
bool IsMessagePackFile(const std::string& path);

// Reads a stella_vslam map.msg. Throws Error naming the file, and the keyframe or landmark, for a
// file that is not MessagePack, an SQLite map database (stella's `sqlite3` map format, which is
// not read: save the map with the `msgpack` format), a missing or malformed field, a non-finite
// number, a zero quaternion, two keyframes at one time, or a map without keyframes.
StellaMap ReadStellaMap(const std::string& path);

}  // namespace epiloc
