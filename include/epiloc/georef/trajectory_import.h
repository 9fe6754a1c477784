// Import of monocular trajectories for georeferencing: `epiloc vo` output and the files users
// already have from ORB-SLAM2/3 and stella_vslam. Parsing is io/pose_files.h (shared with the
// ground-truth readers of eval/truth.h); here the times are put on the drive's clock and poses are
// interpolated at frame and anchor times.
//
//  - tum:   "t x y z qx qy qz qw" (epiloc vo, ORB-SLAM2/3 KeyFrameTrajectory.txt and
//           CameraTrajectory.txt, stella_vslam frame_trajectory.txt / keyframe_trajectory.txt in
//           TUM format). ORB-SLAM3's EuRoC-style files give nanoseconds: timestamps above 1e14
//           are read as nanoseconds.
//  - kitti: 12 numbers per line (ORB-SLAM2 SaveTrajectoryKITTI, stella_vslam KITTI format): line i
//           is the i-th frame; its time is line i of `times_path` (ORB-SLAM's times.txt), else
//           the time of the i-th frame of the drive (`frame_times`), else i seconds.
//  - stella_map: stella_vslam's map database (map.msg, MessagePack; io/stella_map.h): its
//           keyframes, in time order (auto: a file that starts as a MessagePack map).
// ORB-SLAM and KITTI odometry times are seconds since the sequence start: give `time_offset_s`
// (added to every time) or `relative_times` (offset = time of the drive's first frame; KITTI
// poses timed by the drive's frames are on its clock already and keep their times).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "epiloc/core/types.h"
#include "epiloc/io/pose_files.h"
#include "epiloc/io/stella_map.h"

namespace epiloc {

enum class TrajectoryFileFormat { kAuto, kTum, kKitti, kStellaMap };
// "auto", "tum", "kitti", "stella_map"; unknown names throw Error.
TrajectoryFileFormat ParseTrajectoryFileFormat(const std::string& name);

struct TrajectoryImportOptions {
  TrajectoryFileFormat format = TrajectoryFileFormat::kAuto;  // auto: 8 numbers tum, 12 kitti
  std::string times_path;                                     // kitti: one time per line (optional)
  double time_offset_s = 0.0;                                 // added to every timestamp
  bool relative_times = false;      // add the first frame time of `frame_times` instead
  std::vector<double> frame_times;  // the drive's frame times, in order (optional)
  // The drive's frame numbers, one per frame time (optional): a pose within 1 ms of a frame time
  // takes that frame's number (TUM files have none; KITTI line indices are replaced).
  std::vector<frame_t> frame_numbers;

  // Throws Error naming the invalid field.
  void Check() const;
};

// A monocular trajectory on the drive's clock: world_from_cam poses in strictly increasing time.
struct ImportedTrajectory {
  std::string path;
  TrajectoryFileFormat format = TrajectoryFileFormat::kTum;
  std::vector<StampedPose> poses;
};

// The drive directory a trajectory names in a "# drive_dir <path>" comment (`epiloc vo` writes
// one), "" when it names none. Throws Error when the file cannot be opened.
std::string TrajectoryDriveDir(const std::string& path);

// Reads and re-times a trajectory. Throws Error "<path>:<line>: ..." for malformed lines (see
// io/pose_files.h), "<path>: ..." for an empty file, relative_times without frame times, or KITTI
// poses that do not match a given number of frame times.
// A stella_vslam map is read whole; `stella_map` (optional) then gets it (its keyframes as read,
// before the re-timing), so that its landmarks need not be read again.
ImportedTrajectory ImportTrajectory(const std::string& path,
                                    const TrajectoryImportOptions& options,
                                    StellaMap* stella_map = nullptr);

// The pose at `timestamp_s`: the pose itself when within 1 ms of one, else linear interpolation
// of the centre and slerp of the rotation between the neighbours, provided they are at most
// `max_gap_s` apart. nullopt outside the trajectory or across a larger gap.
std::optional<Rigid3d> InterpolatePose(const std::vector<StampedPose>& poses,
                                       double timestamp_s,
                                       double max_gap_s);

}  // namespace epiloc
