// Ground-truth readers of `epiloc evaluate`: every format becomes a PositionTrack (WGS-84
// positions with times, and frame numbers where the format has them).
//
// Formats and the conventions assumed:
//  - drive       a drive directory's ground truth (LoadDrive(dir).ground_truth): the camera's
//                optical centre, e.g. KITTI OXTS moved to the camera by import-kitti.
//  - kitti_oxts  a KITTI OXTS folder (data/NNNNNNNNNN.txt + timestamps.txt), or a KITTI raw drive
//                folder holding one in oxts/: the position of the OXTS unit (IMU), NOT of the
//                camera; frame = file number. Give TruthOptions::lever_arm_m (the camera centre in
//                the IMU frame: x forward, y left, z up; about (1.08, -0.32, 0.73) m for KITTI's
//                cam0 at 2011_09_26) to move it, or use the drive directory written by
//                import-kitti for camera-centred truth.
//  - tum         TUM RGB-D text: "t x y z qx qy qz qw" per line, '#' comments; x, y, z in a
//                z-up pose frame with ENU axes rotated by yaw_deg about up; orientation ignored.
//  - kitti_poses KITTI odometry poses: 12 numbers per line, the row-major 3x4 [R | t] of
//                world_from_camera; the world frame has camera axes (x right, y down, z forward)
//                of a level camera: with yaw_deg = 0 its x points east, y down and z north, so
//                x_in_enu = Rz(yaw) * (x, z, -y). Line i (0-based) is frame i; its time is line i
//                of TruthOptions::times_path (see ReadTimestamps) or, without one, i seconds
//                (then associate by frame).
//  - ndt         NDT (LiDAR map matching) poses, CSV: time, x, y, z, roll, pitch, yaw (metres,
//                radians), either headerless in that order or with a header naming the columns
//                (time|timestamp|timestamp_s, x|x_m, y|y_m, z|z_m, roll, pitch, yaw; optional
//                frame). Map frame: z up, ENU axes rotated by yaw_deg. The pose is the sensor's,
//                enu_from_sensor = Rz(yaw) * Ry(pitch) * Rx(roll) (x forward, y left, z up);
//                lever_arm_m applies as for kitti_oxts.
//  - csv         the position CSV of position_readers.h (lat_deg,lon_deg,alt_m or x_m,y_m,z_m
//                about `origin`).
// tum, kitti_poses and ndt positions are metres about TruthOptions::origin (required), rotated:
// x_in_enu = Rz(yaw_deg) * x_in_pose_frame (counter-clockwise seen from above).
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {

enum class TruthFormat { kAuto, kDrive, kKittiOxts, kTum, kKittiPoses, kNdt, kCsv };

// "auto", "drive", "kitti_oxts", "tum", "kitti_poses", "ndt", "csv"; unknown names throw Error.
TruthFormat ParseTruthFormat(const std::string& name);
std::string TruthFormatName(TruthFormat format);

struct TruthOptions {
  TruthFormat format = TruthFormat::kAuto;  // kAuto: DetectTruthFormat
  std::optional<Geodetic> origin;           // of local pose frames (tum, kitti_poses, ndt, csv x_m)
  double yaw_deg = 0.0;                     // pose frame relative to ENU, about up, CCW
  std::optional<Eigen::Vector3d> lever_arm_m;  // camera centre in the IMU/sensor frame (oxts, ndt)
  std::string times_path;                      // timestamps of kitti_poses lines (optional)

  // Throws Error naming the invalid field.
  void Check() const;
};

// The format of `path`: a directory with drive.json -> drive; with data/ and timestamps.txt, or
// with oxts/ -> kitti_oxts; a file is sniffed from its first data line: 8 whitespace-separated
// numbers -> tum, 12 -> kitti_poses, a CSV header with lat_deg or x_m and timestamp_s -> csv, with
// roll/pitch/yaw or 7 comma-separated numbers -> ndt. Throws Error if none fits.
TruthFormat DetectTruthFormat(const std::string& path);

// Reads ground truth from `path`. Throws Error naming the file and line of a bad entry, a missing
// origin, times not strictly increasing, or an empty track.
PositionTrack ReadTruth(const std::string& path, const TruthOptions& options);

// x_in_enu = Rz(yaw_deg) * x, the rotation of the pose frames above.
Eigen::Matrix3d EnuFromPoseFrame(double yaw_deg);
// The KITTI-poses world frame (x right, y down, z forward) to a z-up frame: (x, y, z) -> (x, z,
// -y).
Eigen::Matrix3d ZUpFromCameraAxes();

}  // namespace epiloc
