// Import of a KITTI raw drive ("synced + rectified" layout) as an epiloc drive directory.
//
// Input layout (Geiger et al., "Vision meets Robotics: The KITTI Dataset", IJRR 2013):
//   <date>/calib_cam_to_cam.txt, calib_velo_to_cam.txt, calib_imu_to_velo.txt
//   <date>/<date>_drive_NNNN_sync/image_0N/{data/NNNNNNNNNN.png, timestamps.txt}
//                                 oxts/{data/NNNNNNNNNN.txt, timestamps.txt}
//                                 velodyne_points/{data/NNNNNNNNNN.bin, timestamps.txt} (optional)
//
// Frames and conventions:
//  - OXTS gives the IMU pose: enu_from_imu = Rz(yaw) * Ry(pitch) * Rx(roll), IMU x forward,
//    y left, z up, yaw 0 = east, counter-clockwise (EnuFromImu).
//  - calib_imu_to_velo R,T = velo_from_imu; calib_velo_to_cam R,T = cam0_from_velo; R_rect_00 =
//    rectified cam0 from cam0. Rectified camera N has the rectified cam0 axes and its centre at
//    c = -K^-1 * P_rect_0N[:, 3] in rectified-cam0 coordinates (camera 1: ~0.54 m along +x).
//  - The camera centre's position is EnuFrame(oxts position).ToGeodetic(enu_from_imu * c_in_imu)
//    (exact geodesy, not KITTI's Mercator projection); its orientation enu_from_cam refers to the
//    local ENU frame at the camera centre.
//
// Output: frames = the PNGs of image_0N (absolute paths, not copies; frame ids = KITTI frame
// numbers), camera = rectified camera N (P_rect_0N intrinsics, S_rect_0N size, no distortion),
// ground truth = the camera track at the frames' trigger times or at the OXTS timestamps (frame
// column set; see FrameTime), GNSS = ground-truth
// positions without orientation, or with simulated consumer-GPS errors (below), LiDAR = every
// velodyne_points/data/*.bin present, with the sensor pose of the IMU track interpolated at the
// scan's timestamp composed with imu_from_velo, format "kitti_bin".
//
// OXTS positions fused with the unit's own velocity (oxts_positions = kFused, the default): on
// drive 0005 the steps between consecutive OXTS positions are 81-96 % of the INS velocity times
// the time step across the open square (frames 3-15 and 49-71) and 98-101 % in the streets, and
// structure triangulated from those positions lies at 0.90 of the LiDAR's depth there: the raw
// positions squeeze the track (the unit reports 0.4-0.5 m position accuracy, posmode 4/5, not an
// RTK fix). FuseOxtsPositions makes the track's steps agree with the velocity and its shape with
// the positions, each weighted by the accuracy the record reports (the fused steps there are
// 93-98 % of speed x dt, no position moves by more than 0.55 m); the orientations are the
// unit's. Records without positive accuracies (an incomplete file) are imported raw.
//
// Simulated GNSS error (gps_noise_sigma_m = s > 0), applied in the local ENU frame at each OXTS
// sample: per axis e = b + w, with b a first-order Gauss-Markov bias of time constant 60 s and
// steady-state sigma 0.9 s (initial value drawn from the steady state; between samples dt apart
// b <- b * exp(-dt/60) + N(0, (0.9 s)^2 * (1 - exp(-2 dt/60)))) and w white noise of sigma
// s * sqrt(1 - 0.81), so each axis has total sigma s; the Up axis uses 1.5 times both sigmas.
// Random numbers come from std::mt19937_64(seed) through a Box-Muller transform written here, so
// the same seed gives the same track on every platform.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {

// Largest simulated GNSS error sigma KittiImportOptions accepts, metres.
constexpr double kMaxGpsNoiseSigmaM = 1000.0;

struct KittiImportOptions {
  std::string raw_drive_dir;       // <date>/<date>_drive_NNNN_sync (calibration files one level up)
  int camera = 0;                  // camera number N in 0..3 (image_0N)
  int64_t start = 0;               // first KITTI frame number kept
  int64_t stop = -1;               // one past the last frame kept, exclusive; -1 = to the end
  int64_t step = 1;                // keep frames start, start + step, ...
  double gps_noise_sigma_m = 0.0;  // per-axis horizontal GNSS error sigma, metres; 0 = GNSS = truth
  uint64_t seed = 1;               // seed of the GNSS error model
  std::string out_dir;             // drive directory written; empty = return the Drive only
  std::string name;                // drive name; empty = "kitti_<date>_<drive>_cam<N>"
  enum class OxtsPositions { kFused, kRaw };
  OxtsPositions oxts_positions = OxtsPositions::kFused;  // see above
  // The time of a frame. kImage: image_0N/timestamps.txt, the ground truth at the OXTS
  // timestamps. kTrigger: the Velodyne's forward-facing time of the frame
  // (velodyne_points/timestamps.txt; KITTI's readme: the cameras are triggered by the scanner
  // facing forward), and the ground truth the camera track interpolated there, one row per frame
  // of the span. On drive 0005 the images' timestamps are 17 ms after the trigger and the OXTS
  // rows 13-21 ms after it, so the kImage truth of a frame is where the camera was 0.06-0.11 m
  // later (README, "The along-road lag"). kAuto (the default): kTrigger when the Velodyne's
  // timestamps are there, kImage otherwise (logged; an image-only download has no trigger times).
  enum class FrameTime { kAuto, kImage, kTrigger };
  FrameTime frame_time = FrameTime::kAuto;

  // Throws Error naming the invalid field.
  void Check() const;
};

// Imports a KITTI raw drive (see above) and writes it to options.out_dir (WriteDrive) when set.
// Frames outside [start, stop) or off the step are dropped; positions and LiDAR scans cover the
// whole [start, stop) span. Throws Error naming the file for a missing calibration file or key, a
// camera whose images are absent, an empty selection or malformed data.
Drive ImportKitti(const KittiImportOptions& options);

// One OXTS record (first six of the 30 values, the rest kept in `values`).
struct OxtsRecord {
  frame_t frame = kInvalidFrame;  // file number
  double timestamp_s = 0.0;       // UNIX seconds from timestamps.txt
  Geodetic position;              // of the OXTS unit
  double roll_rad = 0.0;          // 0 = level, positive = left side up
  double pitch_rad = 0.0;         // 0 = level, positive = front down
  double yaw_rad = 0.0;           // 0 = east, positive = counter-clockwise
  std::vector<double> values;     // all 30 values in dataformat.txt order
};

// Reads <oxts_dir>/data/*.txt with their times from <oxts_dir>/timestamps.txt (line n = file n),
// sorted by frame. Throws Error "<file>:<line>: ..." for a file without 30 numbers, a missing
// timestamp, times not strictly increasing or lat/lon out of range.
std::vector<OxtsRecord> ReadKittiOxts(const std::string& oxts_dir);

// The OXTS unit's positions made consistent with its velocity, by linear least squares per ENU
// axis over positions p_i and slow velocity errors e_i:
//   (p_i - g_i) / a_i                                  g_i recorded, a_i = pos_accuracy
//   (p_(i+1) - p_i - ((v_i + v_(i+1)) / 2 + e_i) dt_i) / (5 mm/s * dt_i)     v_i = (ve, vn, vu)
//   (e_(i+1) - phi_i e_i) / (b_i sqrt(1 - phi_i^2)), e_0 / b_0      phi_i = exp(-dt_i / 10 s)
// with b_i = vel_accuracy: the velocity's error is a first-order Gauss-Markov process (a GNSS/INS
// solution's error drifts over seconds; it does not jump between samples) whose steady-state
// sigma is the reported accuracy. Over a few samples the steps follow the velocity; over tens
// of seconds the positions set the shape (on drive 0005 the localization figures change by
// under 5 mm for time constants from 2 to 100 s). Accuracies below 1 cm and 5 mm/s are raised
// to those. Returns the recorded positions unchanged (fused = false, why_not says why) when a
// record lacks a positive finite accuracy.
struct FusedOxts {
  std::vector<Geodetic> positions;  // one per record
  bool fused = false;
  std::string why_not;               // when not fused
  double max_correction_m = 0.0;     // largest horizontal move of a position
};
FusedOxts FuseOxtsPositions(const std::vector<OxtsRecord>& records);

// enu_from_imu = Rz(yaw) * Ry(pitch) * Rx(roll), angles in radians.
Eigen::Matrix3d EnuFromImu(double roll_rad, double pitch_rad, double yaw_rad);

}  // namespace epiloc
