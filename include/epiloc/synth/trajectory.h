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
#include "epiloc/synth/drive_line.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/world.h"

namespace epiloc {

// A different speed over a part of the drive; fractions of the drive's length.
struct SpeedSection {
  double from_fraction = 0.0;
  double to_fraction = 0.0;
  double speed_mps = 0.0;
};

// A full stop at a fraction of the drive's length (or, when at_m >= 0, at_m metres of s after the
// drive's start), for `duration_s`.
struct StopEvent {
  double at_fraction = 0.0;
  double duration_s = 0.0;
  double at_m = -1.0;
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
  // The drive covers s in [start_offset, length - end_offset]; negative offsets start before or
  // end after the surveyed stretch [0, length] (GenerateSynthetic bounds them by the world's
  // margins).
  double start_offset_m = 0.0;
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

  // Motion and camera variants (issue 14). The defaults leave the drive as above.
  // Between the speed profile's 5 cm steps s(t) follows constant acceleration, so frames from
  // rest and around stops move as the profile says; false: linear in t within a step (the
  // original profile, whose frame-to-frame acceleration is jerky at low speed).
  bool constant_acceleration = false;
  bool start_from_rest = false;  // starts standing and accelerates at max_accel_mps2
  double end_stop_s = -1.0;      // >= 0: brakes to a stop at the end and stands this long
  double creep_mps = 0.0;        // > 0: creeps at this speed over the first creep_m of the drive
  double creep_m = 10.0;
  // While standing (stops, end stop) the camera is still: no wobble, and GenerateSynthetic writes
  // the same image, so the frames of a stop are identical in pose and pixels.
  bool still_when_stopped = false;
  double curve_cut_m = 0.0;    // cuts the inside of every curve by up to this much (DriveLine)
  double curve_ramp_m = 10.0;  // ... reached this far into the curve
  // Starts on the world's side street, turn_approach_m before the turn, and turns right into the
  // street's lane (World::side_street; start_offset_m is then unused).
  bool turn_in = false;
  double turn_radius_m = 10.0;           // radius of the turn (of the camera's path)
  double turn_approach_m = 30.0;         // driven on the side street before the turn
  double turn_lateral_accel_mps2 = 2.5;  // the turn is taken at most at sqrt(this * radius)
  int jpeg_quality = 0;                  // 1-100: frames stored as JPEG of this quality; 0: PNG
  bool grey = false;                     // frames stored as single-channel grey images

  // The survey defaults: 800x400 pinhole camera (fx 600), right lane centre, 8 m/s, 10 Hz, survey
  // grade GNSS/INS (0.3 m, 10 Hz, with orientation).
  static DriveOptions Survey();
  // The query defaults: 640x360 dashcam (fx 500, mild barrel distortion), 0.7 m left of the lane
  // centre, 1.5 m high, 6 m/s with a 2 s stop and a 10 m/s part, 15 Hz, 10 m shorter at both
  // ends, 0.5 deg wobble, noise, darker exposure, motion blur, 3 m GNSS at 1 Hz.
  static DriveOptions Query();

  void Check(const std::string& where) const;
};

// The exact motion of one drive through a world: its line (DriveLine: the lane at the drive's
// lateral offset, optionally cutting curves, optionally after a turn in from the side street) and
// its speed profile along s. Copies what it needs of the world.
class DrivePath {
 public:
  // `length_m`: the survey's driven length (usually world.options.length_m); `seed` sets the
  // wobble phases. Throws Error for invalid options or a turn in without a side street.
  DrivePath(const World& world, const DriveOptions& options, double length_m, uint64_t seed);

  double start_time_s() const { return options_.start_time_s; }
  double end_time_s() const { return options_.start_time_s + times_.back(); }
  double start_s_m() const { return s_.front(); }
  double end_s_m() const { return s_.back(); }
  // Timestamps of the frames: start + i / frame_rate up to the end.
  std::vector<double> FrameTimes() const;

  // The line's parameter s (DriveLine: the along-road distance on the street) at a time (clamped
  // to the drive), and the first time s is reached.
  double SAt(double timestamp_s) const;
  double TimeAtS(double s_m) const;
  // Exact camera pose at a time (x_cam = R * x_world + t), wobble included.
  Rigid3d CamFromWorld(double timestamp_s) const;
  // Level sensor pose (x forward along the line, y left, z up) at s, `height_m` above the road on
  // this drive's line.
  Rigid3d WorldFromSensorAtS(double s_m, double height_m) const;
  const DriveLine& line() const { return line_; }

 private:
  // Time since the start spent moving (stands excluded) at time t since the start.
  double MovingTime(double t) const;

  DriveLine line_;
  double road_height_m_ = 0.0;
  DriveOptions options_;
  std::vector<double> times_;   // time since start, non-decreasing (flat parts: none)
  std::vector<double> s_;       // line parameter s, non-decreasing (flat parts: stops)
  std::vector<double> moving_;  // time spent moving up to times_[i]
  std::vector<double> v_;       // speed ds/dt at times_[i]
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
