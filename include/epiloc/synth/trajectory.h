// Where a synthetic vehicle is when: a speed profile along the road turned into exact camera poses,
// a GNSS model and ground truth in the form a drive stores them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "epiloc/camera/camera.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/world.h"

namespace epiloc {

// A different speed over a part of the drive; fractions of the drive's length.
struct SpeedSection {
  double from_fraction = 0.0;
  double to_fraction = 0.0;
  double speed_mps = 0.0;
};

// A full stop at a fraction of the drive's length, for `duration_s`.
struct StopEvent {
  double at_fraction = 0.0;
  double duration_s = 0.0;
};

// GNSS errors: a first-order Gauss-Markov bias (correlation time tau, standard deviation
// bias_fraction * sigma) plus white noise taking the rest of the variance, so each axis has
// standard deviation sigma (east, north) or up_factor * sigma (up).
struct GnssOptions {
  double sigma_m = 3.0;           // horizontal standard deviation per axis
  double up_factor = 1.5;         // the vertical error is this much larger
  double tau_s = 60.0;            // correlation time of the bias
  double bias_fraction = 0.9;     // bias standard deviation / sigma (white noise: sqrt(1 - f^2))
  double rate_hz = 1.0;           // samples per second
  bool with_orientation = false;  // also report the camera orientation (an INS)
  double orientation_sigma_deg = 0.1;  // its error per axis

  void Check(const std::string& where) const;
};

// One simulated drive: camera, path, speed, image effects and GNSS.
struct DriveOptions {
  std::string name = "synth";     // drive name (drive.json)
  Camera camera;                  // calibration of the frames (distortion allowed)
  double lateral_offset_m = 0.0;  // from the right lane centre, positive to the left
  double camera_height_m = 1.6;   // optical centre above the road
  double start_offset_m = 0.0;    // the drive covers s in [start_offset, length - end_offset]
  double end_offset_m = 0.0;
  double speed_mps = 8.0;              // cruising speed
  std::vector<SpeedSection> sections;  // other speeds over parts of the drive
  std::vector<StopEvent> stops;        // full stops
  double max_accel_mps2 = 1.5;         // speed changes and stops use at most this
  double frame_rate_hz = 10.0;         // frames per second
  double start_time_s = 1700000000.0;  // timestamp of the first frame (UNIX seconds)
  double wobble_yaw_deg = 0.0;         // amplitude of the heading wobble (two sinusoids)
  double wobble_pitch_deg = 0.0;       // amplitude of the pitch wobble
  double wobble_period_s = 2.7;        // heading wobble period; pitch uses 0.63 of it
  double mount_yaw_deg = 0.0;          // fixed camera yaw relative to the road, left positive
  double mount_pitch_deg = 0.0;        // fixed camera pitch, up positive
  double exposure_s = 0.0;             // motion blur over this exposure time (0 = sharp)
  RenderOptions render;                // supersampling, noise, gain (seed set per frame)
  GnssOptions gnss;                    // the drive's GNSS receiver
  double max_gap_s = 1.0;              // Drive::max_gap_s written to drive.json

  // The survey defaults: 800x400 pinhole camera (fx 600), right lane centre, 8 m/s, 10 Hz, survey
  // grade GNSS/INS (0.3 m, 10 Hz, with orientation).
  static DriveOptions Survey();
  // The query defaults: 640x360 dashcam (fx 500, mild barrel distortion), 0.7 m left of the lane
  // centre, 1.5 m high, 6 m/s with a 2 s stop and a 10 m/s part, 15 Hz, 10 m shorter at both
  // ends, 0.5 deg wobble, noise, darker exposure, motion blur, 3 m GNSS at 1 Hz.
  static DriveOptions Query();

  void Check(const std::string& where) const;
};

// The exact motion of one drive through a world. Copies what it needs of the world.
class DrivePath {
 public:
  // `length_m`: the survey's driven length (usually world.options.length_m); `seed` sets the
  // wobble phases.
  DrivePath(const World& world, const DriveOptions& options, double length_m, uint64_t seed);

  double start_time_s() const { return options_.start_time_s; }
  double end_time_s() const { return options_.start_time_s + times_.back(); }
  double start_s_m() const { return s_.front(); }
  double end_s_m() const { return s_.back(); }
  // Timestamps of the frames: start + i / frame_rate up to the end.
  std::vector<double> FrameTimes() const;

  // Along-road distance at a time (clamped to the drive), and the first time s is reached.
  double SAt(double timestamp_s) const;
  double TimeAtS(double s_m) const;
  // Exact camera pose at a time (x_cam = R * x_world + t), wobble included.
  Rigid3d CamFromWorld(double timestamp_s) const;
  // Level sensor pose (x forward along the road, y left, z up) at distance s, `height_m` above
  // the road on this drive's lateral position.
  Rigid3d WorldFromSensorAtS(double s_m, double height_m) const;

 private:
  Centreline centreline_;
  double lane_offset_m_ = 0.0;
  double road_height_m_ = 0.0;
  DriveOptions options_;
  std::vector<double> times_;  // time since start, non-decreasing (flat parts: none)
  std::vector<double> s_;      // along-road distance, non-decreasing (flat parts: stops)
  double phase_[4] = {0, 0, 0, 0};
};

// Rotation taking vectors in world ENU (about `world_frame`'s origin) into the local ENU frame at
// `position`.
Eigen::Matrix3d LocalEnuFromWorldEnu(const EnuFrame& world_frame, const Geodetic& position);

// GNSS samples of a drive's camera centre with the errors of `options` (deterministic for seed).
PositionTrack SimulateGnss(const DrivePath& path,
                           const EnuFrame& world_frame,
                           const GnssOptions& options,
                           uint64_t seed,
                           const std::string& source = "gnss.csv");

// Exact camera positions and orientations (enu_from_cam in the local ENU at each position) at the
// given frame times; sample i gets frame number i.
PositionTrack GroundTruthTrack(const DrivePath& path,
                               const EnuFrame& world_frame,
                               const std::vector<double>& frame_times_s,
                               const std::string& source = "ground_truth.csv");

}  // namespace epiloc
