// Camera trajectories in the text formats of SLAM and odometry tools: TUM (ORB-SLAM2/3
// KeyFrameTrajectory.txt and CameraTrajectory.txt, stella_vslam frame/keyframe trajectories,
// `epiloc vo`) and KITTI odometry poses (ORB-SLAM2 SaveTrajectoryKITTI, stella_vslam "KITTI").
// The poses are read as written, in the tool's own world frame; what that frame means (ENU, a
// level camera, a monocular SLAM frame of unknown scale) is the caller's business (eval/truth.h
// for ground truth, georef/ for monocular trajectories).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "epiloc/core/types.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

// One pose of a trajectory file: world_from_cam (x_in_world = R * x_in_cam + t; the camera centre
// is the translation) at a time.
struct StampedPose {
  double timestamp_s = 0.0;       // as written in the file (seconds for TUM; see ReadKittiPoses)
  frame_t frame = kInvalidFrame;  // KITTI poses: line index (0-based); TUM: none
  Rigid3d world_from_cam;
  int64_t line = 0;  // line of the file it was read from (1-based), for messages
};

// TUM trajectory: "timestamp tx ty tz qx qy qz qw" per line (whitespace-separated), '#' comments
// and blank lines skipped. The quaternion is normalised; one further than 1e-3 from unit length
// (or zero) is an error. Throws Error "<path>:<line>: ..." for a line without 8 numbers, a
// non-finite number, a bad quaternion or a timestamp not after the one before; "<path>: cannot
// open ..." for a missing file. An empty file gives an empty vector.
std::vector<StampedPose> ReadTumPoses(const std::string& path);

// KITTI odometry poses: 12 numbers per line, the row-major 3x4 [R | t] of world_from_cam. Line i
// (0-based, comments and blank lines not counted) is frame i; its time is line i of `times_path`
// (ReadTimestamps: seconds or KITTI date-times; for KITTI odometry and ORB-SLAM's times.txt these
// are seconds since the sequence start) or, when `times_path` is empty, i seconds. R is
// orthonormalised; one further than 1e-3 from a rotation is an error unless `check_rotation` is
// false (then only the translation is meaningful). Throws Error "<path>:<line>: ..." for a
// malformed line or a pose without a timestamp.
std::vector<StampedPose> ReadKittiPoses(const std::string& path,
                                        const std::string& times_path = "",
                                        bool check_rotation = true);

// Writes a TUM trajectory (full double precision for times and translations): `comments` first,
// each as a '#' line, then one line per pose. Throws Error on I/O failure.
void WriteTumPoses(const std::vector<StampedPose>& poses,
                   const std::string& path,
                   const std::vector<std::string>& comments = {});

}  // namespace epiloc
