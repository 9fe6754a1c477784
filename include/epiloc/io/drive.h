// A drive: camera frames with timestamps, GNSS positions the localizer may use, optional ground
// truth kept apart from them, the camera calibration and optional LiDAR scans with their poses.
// On disk a drive is a directory with a manifest `drive.json` (format in README.md, section
// "Drive directory format", also docs/drive_format.md) that points at the user's own files: an
// image folder, a CSV of frames or a video; positions as CSV (lat/lon/alt or local x/y/z), NMEA
// GGA/RMC or a KITTI OXTS folder (readers in position_readers.h).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "epiloc/camera/camera.h"
#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"

namespace epiloc {

// One camera frame. `image` is a path (absolute, or relative to the drive directory) of an image
// file, or, for a video drive, empty (the frame is the video's frame number `frame`).
struct FrameRecord {
  frame_t frame = kInvalidFrame;  // the drive's own frame number (KITTI frame number, video index)
  double timestamp_s = 0.0;       // seconds, same clock as the positions (UNIX time for real data)
  std::string image;
  int64_t line = 0;  // of the frames CSV (0 for frames from a folder or a video); not compared

  bool operator==(const FrameRecord& other) const;
};

// A position (of the camera's optical centre) at a time. `enu_from_cam`, when known, rotates
// camera-frame vectors (x right, y down, z forward) into the local ENU frame at `position`.
struct PositionSample {
  double timestamp_s = 0.0;
  Geodetic position;
  std::optional<Eigen::Quaterniond> enu_from_cam;
  frame_t frame = kInvalidFrame;  // set when the source ties the sample to a frame

  // Exact equality of every field (orientations compared coefficient by coefficient).
  bool operator==(const PositionSample& other) const;
};

// Samples sorted by strictly increasing time.
struct PositionTrack {
  std::string source;  // file the samples came from, for messages
  std::vector<PositionSample> samples;

  // Position at `timestamp_s`, linear in a local ENU frame between the neighbouring samples (and
  // slerp of orientations). Returns nullopt if the nearest sample on either side is more than
  // `max_gap_s` away, or if t lies before the first / after the last sample by more than
  // `max_gap_s` (within that, the end segment is extrapolated).
  //
  // The ENU frame is the one about the earlier sample of the segment; orientations are first
  // expressed in that frame (ENU axes turn with position) and the result is given in the ENU frame
  // at the interpolated position. The result has an orientation only if both neighbours have one
  // (a single-sample track: that sample's), `timestamp_s` as its time and `frame` = kInvalidFrame
  // unless `timestamp_s` equals a sample's time exactly (then that sample is returned as is).
  std::optional<PositionSample> Interpolate(double timestamp_s, double max_gap_s) const;
};

// A LiDAR scan file and the pose of the sensor when it was taken.
struct LidarScan {
  int64_t scan = -1;  // the drive's scan number (KITTI: frame number of the scan)
  double timestamp_s = 0.0;
  std::string path;    // absolute, or relative to the drive directory
  std::string format;  // "kitti_bin" (N x 4 float32 x,y,z,reflectance), "ply", "pcd", "xyz"
  Geodetic sensor_position;
  Eigen::Quaterniond enu_from_sensor = Eigen::Quaterniond::Identity();  // local ENU at position

  bool operator==(const LidarScan& other) const;
};

struct Drive {
  std::string dir;      // the drive directory (where drive.json is)
  std::string name;     // unique name of the drive, e.g. "kitti_2011_09_26_0005_cam0"
  Camera camera;        // calibration of the frames as stored (may have distortion)
  bool colour = false;  // frames are colour images (informative; readers load as stored)
  std::string video;    // video file when the frames come from one, else empty
  std::string frames_csv;  // the frames CSV resolved against `dir` ("" for a folder or video)
  std::vector<FrameRecord> frames;            // sorted by timestamp; frame numbers unique
  PositionTrack gnss;                         // may be empty (no GNSS)
  std::optional<PositionTrack> ground_truth;  // kept apart: never read by the localizer
  std::vector<LidarScan> lidar;
  double max_gap_s = 0.5;  // positions further than this from a frame leave it unpositioned

  // Path of a frame's image resolved against `dir`.
  std::string ImagePath(const FrameRecord& frame) const;
  // "<frames_csv>:<line>" of a frame read from the frames CSV, else "".
  std::string FrameWhere(const FrameRecord& frame) const;
  // `video` resolved against `dir` ("" when the drive has no video).
  std::string VideoPath() const;
  // Path of a LiDAR scan file resolved against `dir`.
  std::string ScanPath(const LidarScan& scan) const;
};

// Reads `dir`/drive.json and everything it refers to. Throws Error naming the file (and line) for
// a missing or malformed file, timestamps going backwards, a calibration that does not fit the
// images, out-of-range lat/lon, ...
//
// Checks made: unknown keys in drive.json (typos), missing calibration fields, Camera::Check, the
// first frame's image size against the calibration, every image file exists, frame numbers are
// unique and frame times never decrease, position times strictly increase, lat/lon in range.
// `time_offset_s` of the manifest is added to the GNSS and ground-truth timestamps.
Drive LoadDrive(const std::string& dir);

// The camera calibration of a drive.json-style file: its "camera" object as in drive.json (other
// keys are ignored, so a drive's own drive.json serves). Throws Error naming the file for a
// missing or malformed calibration.
Camera ReadCalibrationFile(const std::string& path);

// The existing files and folders a drive directory's manifest names: `dir`/drive.json first, then
// the frames CSV or image folder, video, timestamps, position files and folders, LiDAR CSV,
// then the images the frames CSV and the scans the LiDAR CSV name, resolved against `dir`; for commands that must not write over their inputs. Reads only the
// manifest and checks nothing: a missing or malformed one gives drive.json alone (the loader
// reports it).
std::vector<std::string> DriveInputPaths(const std::string& dir);

// Writes a drive in the canonical layout: drive.json, frames.csv, gnss.csv, ground_truth.csv,
// lidar.csv (the files present in the Drive), with full double precision, so that
// LoadDrive(dir) gives back the same drive. Image, video and scan paths are written as given when
// `dir` is the drive's own directory (or drive.dir is empty); otherwise relative paths are
// resolved against drive.dir and written absolute, so the new manifest still finds the files.
// Creates `dir` if needed.
void WriteDrive(const Drive& drive, const std::string& dir);

// The position of each frame of a drive: `per_frame[i]` is track.Interpolate(frames[i].timestamp_s,
// drive.max_gap_s) (with `frame` set to the frame's number), `missing` the frame numbers that got
// none, in drive order.
struct FramePositions {
  std::vector<std::optional<PositionSample>> per_frame;
  std::vector<frame_t> missing;
};
// Logs one warning (spdlog) with the number of unpositioned frames and the first few of them.
FramePositions PositionFrames(const Drive& drive, const PositionTrack& track);

}  // namespace epiloc
