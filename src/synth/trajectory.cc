#include "epiloc/synth/trajectory.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr double kStepM = 0.05;  // resolution of the speed profile

// world_from_cam rotation for a camera looking along yaw (from east, counter-clockwise) and
// pitch (up positive): columns are the camera's right, down and forward axes.
Eigen::Matrix3d WorldFromCamRotation(double yaw, double pitch) {
  const Eigen::Vector3d forward(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw),
                                std::sin(pitch));
  const Eigen::Vector3d right(std::sin(yaw), -std::cos(yaw), 0.0);
  Eigen::Matrix3d r;
  r.col(0) = right;
  r.col(1) = forward.cross(right);
  r.col(2) = forward;
  return r;
}

Eigen::Quaterniond SmallRotation(double sigma_rad, Rng& rng) {
  const Eigen::Vector3d v(rng.Normal(), rng.Normal(), rng.Normal());
  const Eigen::Vector3d axis_angle = sigma_rad * v;
  if (axis_angle.norm() < 1e-15) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(axis_angle.norm(), axis_angle.normalized()));
}

}  // namespace

void GnssOptions::Check(const std::string& where) const {
  EPILOC_CHECK(sigma_m >= 0 && sigma_m <= 1000, "{}: gnss sigma_m = {} must be in [0, 1000] m",
               where, sigma_m);
  EPILOC_CHECK(up_factor >= 0, "{}: gnss up_factor must not be negative", where);
  EPILOC_CHECK(tau_s > 0, "{}: gnss tau_s must be positive", where);
  EPILOC_CHECK(bias_fraction >= 0 && bias_fraction <= 1, "{}: gnss bias_fraction must be in [0, 1]",
               where);
  EPILOC_CHECK(rate_hz > 0, "{}: gnss rate_hz must be positive", where);
  EPILOC_CHECK(orientation_sigma_deg >= 0, "{}: gnss orientation_sigma_deg must not be negative",
               where);
}

DriveOptions DriveOptions::Survey() {
  DriveOptions o;
  o.name = "synth_survey";
  o.camera.width = 800;
  o.camera.height = 400;
  o.camera.fx = o.camera.fy = 600.0;
  o.camera.cx = 399.5;
  o.camera.cy = 199.5;
  o.camera_height_m = 1.6;
  o.speed_mps = 8.0;
  o.frame_rate_hz = 10.0;
  o.start_time_s = 1700000000.0;
  o.gnss.sigma_m = 0.3;
  o.gnss.rate_hz = 10.0;
  o.gnss.with_orientation = true;
  o.gnss.orientation_sigma_deg = 0.1;
  o.max_gap_s = 0.5;
  return o;
}

DriveOptions DriveOptions::Query() {
  DriveOptions o;
  o.name = "synth_query";
  o.camera.width = 640;
  o.camera.height = 360;
  o.camera.fx = o.camera.fy = 500.0;
  o.camera.cx = 319.5;
  o.camera.cy = 179.5;
  o.camera.distortion = {-0.08, 0.01, 0.0, 0.0, 0.0};
  o.lateral_offset_m = 0.7;
  o.camera_height_m = 1.5;
  o.start_offset_m = 10.0;
  o.end_offset_m = 10.0;
  o.speed_mps = 6.0;
  o.sections = {{0.55, 0.8, 10.0}};
  o.stops = {{0.3, 2.0}};
  o.frame_rate_hz = 15.0;
  o.start_time_s = 1700000000.0 + 3 * 86400.0 + 5 * 3600.0;
  o.wobble_yaw_deg = 0.5;
  o.wobble_pitch_deg = 0.5;
  o.exposure_s = 1.0 / 150.0;
  o.render.noise_sigma = 2.0;
  o.render.exposure_gain = 0.85;
  o.gnss.sigma_m = 3.0;
  o.gnss.rate_hz = 1.0;
  o.max_gap_s = 1.5;
  return o;
}

void DriveOptions::Check(const std::string& where) const {
  EPILOC_CHECK(!name.empty(), "{}: name is empty", where);
  camera.Check(where + ": camera");
  EPILOC_CHECK(std::isfinite(lateral_offset_m) && std::abs(lateral_offset_m) < 3,
               "{}: lateral_offset_m = {} must be within 3 m of the lane centre", where,
               lateral_offset_m);
  EPILOC_CHECK(camera_height_m > 0.3 && camera_height_m < 5,
               "{}: camera_height_m must be in (0.3, 5)", where);
  EPILOC_CHECK(std::isfinite(start_offset_m) && std::isfinite(end_offset_m),
               "{}: offsets must be finite", where);
  EPILOC_CHECK(speed_mps > 0, "{}: speed_mps must be positive", where);
  for (const SpeedSection& s : sections) {
    EPILOC_CHECK(s.from_fraction >= 0 && s.to_fraction <= 1 && s.from_fraction < s.to_fraction &&
                     s.speed_mps > 0,
                 "{}: speed section [{}, {}] at {} m/s is invalid", where, s.from_fraction,
                 s.to_fraction, s.speed_mps);
  }
  for (const StopEvent& s : stops) {
    EPILOC_CHECK((s.at_m >= 0 ? std::isfinite(s.at_m) : s.at_fraction > 0 && s.at_fraction < 1) &&
                     s.duration_s >= 0 && std::isfinite(s.duration_s),
                 "{}: stop at {} ({} m) for {} s is invalid", where, s.at_fraction, s.at_m,
                 s.duration_s);
  }
  EPILOC_CHECK(max_accel_mps2 > 0, "{}: max_accel_mps2 must be positive", where);
  EPILOC_CHECK(frame_rate_hz > 0, "{}: frame_rate_hz must be positive", where);
  EPILOC_CHECK(std::isfinite(start_time_s), "{}: start_time_s is not finite", where);
  EPILOC_CHECK(std::abs(wobble_yaw_deg) < 10 && std::abs(wobble_pitch_deg) < 10,
               "{}: wobble amplitudes must be below 10 deg", where);
  EPILOC_CHECK(wobble_period_s > 0, "{}: wobble_period_s must be positive", where);
  EPILOC_CHECK(exposure_s >= 0 && exposure_s < 1, "{}: exposure_s must be in [0, 1)", where);
  EPILOC_CHECK(max_gap_s > 0, "{}: max_gap_s must be positive", where);
  render.Check();
  gnss.Check(where);
  EPILOC_CHECK(std::isfinite(end_stop_s), "{}: end_stop_s is not finite", where);
  EPILOC_CHECK(std::isfinite(creep_mps) && creep_mps >= 0 && creep_m > 0,
               "{}: creep_mps must not be negative and creep_m must be positive", where);
  // Beyond 2 m the cut would leave the 3.5 m lane.
  EPILOC_CHECK(curve_cut_m >= 0 && curve_cut_m <= 2 && curve_ramp_m > 0,
               "{}: curve_cut_m = {} must be in [0, 2] and curve_ramp_m positive", where,
               curve_cut_m);
  // A car cannot turn tighter than about 5 m; beyond 15 m the turn leaves an urban junction.
  EPILOC_CHECK(turn_radius_m >= 5 && turn_radius_m <= 15,
               "{}: turn_radius_m = {} must be in [5, 15]", where, turn_radius_m);
  EPILOC_CHECK(turn_approach_m > 0 && turn_lateral_accel_mps2 > 0,
               "{}: turn_approach_m and turn_lateral_accel_mps2 must be positive", where);
  EPILOC_CHECK(jpeg_quality >= 0 && jpeg_quality <= 100,
               "{}: jpeg_quality = {} must be in [0, 100]", where, jpeg_quality);
}

namespace {

// The line of a drive: the lane at its lateral offset, curves cut, after a turn in.
DriveLine MakeLine(const World& world, const DriveOptions& options) {
  options.Check("drive " + options.name);
  DriveLine line(world.centreline, world.RightLaneCentre() + options.lateral_offset_m);
  if (options.curve_cut_m > 0) line.SetCurveCut(options.curve_cut_m, options.curve_ramp_m);
  if (options.turn_in) {
    EPILOC_CHECK(world.side_street.has_value(),
                 "drive {}: turn_in needs a world with a side street", options.name);
    const SideStreet& side = *world.side_street;
    line.SetLeadIn(TurnInLeadIn(world.centreline, side.junction_s_m, side.angle_deg,
                                line.offset_m(), options.turn_radius_m, options.turn_approach_m));
    // The car (1.8 m wide) keeps half its width from the kerbs all the way.
    constexpr double kHalfCarWidthM = 0.9;
    const Centreline& lead_in = *line.lead_in();
    for (double s = lead_in.start_s_m(); s <= lead_in.end_s_m() + 5.0; s += 0.1) {
      EPILOC_CHECK(side.OnAsphalt(world, line.At(s).position_in_world, kHalfCarWidthM),
                   "drive {}: the turn in (radius {} m, approach {} m) leaves the asphalt at "
                   "s = {:.1f} m; choose another radius or a shorter approach",
                   options.name, options.turn_radius_m, options.turn_approach_m, s);
    }
  }
  return line;
}

}  // namespace

DrivePath::DrivePath(const World& world,
                     const DriveOptions& options,
                     double length_m,
                     uint64_t seed)
    : line_(MakeLine(world, options)), road_height_m_(world.RoadHeight()), options_(options) {
  const double s0 = line_.lead_in() ? line_.lead_in()->start_s_m() : options.start_offset_m;
  const double s1 = length_m - options.end_offset_m;
  EPILOC_CHECK(s1 - s0 >= 1.0, "drive {}: nothing left to drive ({} m to {} m)", options.name, s0,
               s1);
  const int n = static_cast<int>(std::ceil((s1 - s0) / kStepM)) + 1;
  std::vector<double> s(n), v(n, options.speed_mps);
  std::vector<double> dwell(n, 0.0);
  for (int i = 0; i < n; ++i) s[i] = std::min(s1, s0 + i * kStepM);
  const auto index_of = [&](double fraction) {
    return std::clamp(static_cast<int>(std::lround(fraction * (s1 - s0) / kStepM)), 0, n - 1);
  };
  for (const SpeedSection& section : options.sections) {
    for (int i = index_of(section.from_fraction); i <= index_of(section.to_fraction); ++i) {
      v[i] = section.speed_mps;
    }
  }
  if (options.creep_mps > 0) {
    for (int i = 0; i < n && s[i] <= s0 + options.creep_m; ++i) v[i] = options.creep_mps;
  }
  if (line_.lead_in()) {
    // Through the turn the lateral acceleration v^2 / R stays within the limit.
    for (const CentrelinePiece& piece : line_.lead_in()->pieces()) {
      if (piece.curvature_per_m == 0) continue;
      const double v_turn =
          std::sqrt(options.turn_lateral_accel_mps2 / std::abs(piece.curvature_per_m));
      for (int i = 0; i < n; ++i) {
        if (s[i] >= piece.s0_m && s[i] <= piece.s0_m + piece.length_m)
          v[i] = std::min(v[i], v_turn);
      }
    }
  }
  for (const StopEvent& stop : options.stops) {
    const int i = stop.at_m >= 0 ? index_of(stop.at_m / (s1 - s0)) : index_of(stop.at_fraction);
    v[i] = 0.0;
    dwell[i] += stop.duration_s;
  }
  if (options.start_from_rest) v[0] = 0.0;
  if (options.end_stop_s >= 0) {
    v[n - 1] = 0.0;
    dwell[n - 1] += options.end_stop_s;
  }
  // Limit accelerations both ways: v^2 changes by at most 2 a ds per step.
  const double a2 = 2.0 * options.max_accel_mps2;
  for (int i = 1; i < n; ++i)
    v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + a2 * (s[i] - s[i - 1])));
  for (int i = n - 2; i >= 0; --i)
    v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + a2 * (s[i + 1] - s[i])));
  double t = 0, moving = 0;
  for (int i = 0; i < n; ++i) {
    if (i > 0) {
      const double dt = 2.0 * (s[i] - s[i - 1]) / std::max(v[i] + v[i - 1], 1e-6);
      t += dt;
      moving += dt;
    }
    times_.push_back(t);
    s_.push_back(s[i]);
    moving_.push_back(moving);
    v_.push_back(v[i]);
    if (dwell[i] > 0) {
      t += dwell[i];
      times_.push_back(t);
      s_.push_back(s[i]);
      moving_.push_back(moving);
      v_.push_back(v[i]);
    }
  }
  Rng rng(MixSeed(seed, 77));
  for (double& p : phase_) p = rng.Uniform(0, 2 * M_PI);
}

double DrivePath::MovingTime(double t) const {
  // Before the start and after the end the vehicle stands if it starts / ends standing.
  if (t <= 0) return options_.start_from_rest ? 0.0 : t;
  if (t >= times_.back()) {
    return moving_.back() + (options_.end_stop_s >= 0 ? 0.0 : t - times_.back());
  }
  const size_t i = std::upper_bound(times_.begin(), times_.end(), t) - times_.begin();
  const double dt = times_[i] - times_[i - 1];
  if (dt <= 0) return moving_[i];
  return moving_[i - 1] + (moving_[i] - moving_[i - 1]) * (t - times_[i - 1]) / dt;
}

std::vector<double> DrivePath::FrameTimes() const {
  std::vector<double> out;
  const double duration = times_.back();
  for (int64_t i = 0; i / options_.frame_rate_hz <= duration + 1e-9; ++i) {
    out.push_back(options_.start_time_s + i / options_.frame_rate_hz);
  }
  return out;
}

double DrivePath::SAt(double timestamp_s) const {
  const double t = timestamp_s - options_.start_time_s;
  if (t <= times_.front()) return s_.front();
  if (t >= times_.back()) return s_.back();
  const size_t i = std::upper_bound(times_.begin(), times_.end(), t) - times_.begin();
  const double dt = times_[i] - times_[i - 1];
  if (dt <= 0) return s_[i];
  const double tau = t - times_[i - 1];
  if (options_.constant_acceleration) {
    // The step's time 2 ds / (v0 + v1) is that of constant acceleration (v1 - v0) / dt.
    const double accel = (v_[i] - v_[i - 1]) / dt;
    return std::min(s_[i], s_[i - 1] + tau * (v_[i - 1] + 0.5 * accel * tau));
  }
  return s_[i - 1] + (s_[i] - s_[i - 1]) * tau / dt;
}

double DrivePath::TimeAtS(double s_m) const {
  if (s_m <= s_.front()) return options_.start_time_s + times_.front();
  if (s_m >= s_.back()) return options_.start_time_s + times_.back();
  const size_t i = std::lower_bound(s_.begin(), s_.end(), s_m) - s_.begin();
  const double ds = s_[i] - s_[i - 1];
  const double dt = times_[i] - times_[i - 1];
  if (options_.constant_acceleration && ds > 0) {
    // Solve s - s0 = v0 tau + a tau^2 / 2 for the first tau >= 0 (a stable form of the root).
    const double accel = (v_[i] - v_[i - 1]) / dt, d = s_m - s_[i - 1];
    const double root = std::sqrt(std::max(0.0, v_[i - 1] * v_[i - 1] + 2 * accel * d));
    const double tau = v_[i - 1] + root > 0 ? 2 * d / (v_[i - 1] + root) : 0.0;
    return options_.start_time_s + times_[i - 1] + std::min(tau, dt);
  }
  const double f = ds > 0 ? (s_m - s_[i - 1]) / ds : 1.0;
  return options_.start_time_s + times_[i - 1] + f * (times_[i] - times_[i - 1]);
}

Rigid3d DrivePath::CamFromWorld(double timestamp_s) const {
  const double s = SAt(timestamp_s);
  const double t_since_start = timestamp_s - options_.start_time_s;
  // A vehicle standing still does not wobble.
  const double t = options_.still_when_stopped ? MovingTime(t_since_start) : t_since_start;
  const double w = 2 * M_PI / options_.wobble_period_s;
  const double yaw_wobble =
      options_.wobble_yaw_deg * kDegToRad *
      (0.8 * std::sin(w * t + phase_[0]) + 0.2 * std::sin(2.7 * w * t + phase_[1]));
  const double pitch_wobble =
      options_.wobble_pitch_deg * kDegToRad *
      (0.8 * std::sin(w / 0.63 * t + phase_[2]) + 0.2 * std::sin(3.1 * w * t + phase_[3]));
  const LinePose pose = line_.At(s);
  const double yaw = pose.yaw_rad + options_.mount_yaw_deg * kDegToRad + yaw_wobble;
  const double pitch = options_.mount_pitch_deg * kDegToRad + pitch_wobble;
  const Eigen::Matrix3d world_from_cam = WorldFromCamRotation(yaw, pitch);
  const Eigen::Vector2d& p = pose.position_in_world;
  const Eigen::Vector3d centre(p.x(), p.y(), road_height_m_ + options_.camera_height_m);
  return Rigid3d::FromMatrix(world_from_cam.transpose(), -world_from_cam.transpose() * centre);
}

Rigid3d DrivePath::WorldFromSensorAtS(double s_m, double height_m) const {
  const LinePose pose = line_.At(s_m);
  const Eigen::Vector2d& p = pose.position_in_world;
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(pose.yaw_rad, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(p.x(), p.y(), road_height_m_ + height_m));
}

Eigen::Matrix3d LocalEnuFromWorldEnu(const EnuFrame& world_frame, const Geodetic& position) {
  return world_frame.EnuFromLocalEnu(position).transpose();
}

PositionTrack SimulateGnss(const DrivePath& path,
                           const EnuFrame& world_frame,
                           const GnssOptions& options,
                           uint64_t seed,
                           const std::string& source) {
  options.Check("gnss");
  Rng rng(seed);
  PositionTrack track;
  track.source = source;
  const double dt = 1.0 / options.rate_hz;
  const double phi = std::exp(-dt / options.tau_s);
  const Eigen::Vector3d scale(options.sigma_m, options.sigma_m,
                              options.sigma_m * options.up_factor);
  const double white = std::sqrt(1.0 - options.bias_fraction * options.bias_fraction);
  Eigen::Vector3d bias(rng.Normal(), rng.Normal(), rng.Normal());  // in units of the bias sigma
  for (int64_t k = 0;; ++k) {
    const double t = path.start_time_s() + k * dt;
    if (t > path.end_time_s() + 1e-9) break;
    if (k > 0) {
      for (int a = 0; a < 3; ++a) bias[a] = phi * bias[a] + std::sqrt(1 - phi * phi) * rng.Normal();
    }
    const Eigen::Vector3d noise(rng.Normal(), rng.Normal(), rng.Normal());
    const Eigen::Vector3d error = scale.cwiseProduct(options.bias_fraction * bias + white * noise);
    const Rigid3d cam_from_world = path.CamFromWorld(t);
    const Eigen::Vector3d centre = cam_from_world.Inverse().translation;
    PositionSample sample;
    sample.timestamp_s = t;
    sample.position = world_frame.ToGeodetic(centre + error);
    if (options.with_orientation) {
      const Eigen::Matrix3d enu_from_cam = LocalEnuFromWorldEnu(world_frame, sample.position) *
                                           cam_from_world.rotation.toRotationMatrix().transpose();
      sample.enu_from_cam = (SmallRotation(options.orientation_sigma_deg * kDegToRad, rng) *
                             Eigen::Quaterniond(enu_from_cam))
                                .normalized();
    }
    track.samples.push_back(sample);
  }
  return track;
}

PositionTrack GroundTruthTrack(const DrivePath& path,
                               const EnuFrame& world_frame,
                               const std::vector<double>& frame_times_s,
                               const std::string& source) {
  PositionTrack track;
  track.source = source;
  for (size_t i = 0; i < frame_times_s.size(); ++i) {
    const Rigid3d cam_from_world = path.CamFromWorld(frame_times_s[i]);
    const Rigid3d world_from_cam = cam_from_world.Inverse();
    PositionSample sample;
    sample.timestamp_s = frame_times_s[i];
    sample.frame = static_cast<frame_t>(i);
    sample.position = world_frame.ToGeodetic(world_from_cam.translation);
    sample.enu_from_cam = Eigen::Quaterniond(LocalEnuFromWorldEnu(world_frame, sample.position) *
                                             world_from_cam.rotation.toRotationMatrix())
                              .normalized();
    track.samples.push_back(sample);
  }
  return track;
}

}  // namespace epiloc
