#include "epiloc/anchor/lidar_track.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <unordered_map>
#include <utility>

#include <spdlog/spdlog.h>

#include "anchor_internal.h"
#include "epiloc/anchor/structure_registration.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/voxel.h"
#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "epiloc/core/statistics.h"

namespace epiloc {
namespace {

// The scan's points (sensor frame) within the range limits, thinned by the voxel filter.
PointCloud ReadThinnedScan(const Drive& drive,
                           const LidarScan& scan,
                           const LidarTrackOptions& options) {
  const PointCloud kept = anchor_internal::ReadScanInRange(drive, scan, options.min_range_m,
                                                           options.max_range_m, false);
  return options.voxel_m > 0 ? VoxelFilter(kept, options.voxel_m) : kept;
}

// Elevation and azimuth of a direction, radians.
std::pair<double, double> ElevationAzimuth(const Eigen::Vector3d& v) {
  return {std::atan2(v.z(), v.head<2>().norm()), std::atan2(v.y(), v.x())};
}

double WrapDeg(double deg) { return std::remainder(deg, 360.0); }

// Registers scan b (its sensor frame) to scan a from the track's a_from_b; fills the step.
LidarTrackStep RegisterPair(const PointCloud& a,
                            const PointCloud& b,
                            const Rigid3d& track_a_from_b,
                            const LidarTrackOptions& options,
                            Rigid3d* lidar_a_from_b) {
  LidarTrackStep step;
  StructureRegistrationOptions r;
  r.max_distances_m = options.max_distances_m;
  // Metric on both sides: no level frees the scale (the check wants a positive distance).
  r.min_scale_distance_m = 0.5 * options.max_distances_m.back();
  r.search_step_m = 0.0;  // the track's step is the seed: no search
  r.search_along_m = 0.0;
  r.profile_moves = 0;
  r.hold_tilt_coarse = false;  // both are whole scans of the same place: nothing to hold
  StructureMap map(a, r);
  std::vector<Eigen::Vector3d> points;
  points.reserve(b.size());
  for (const Eigen::Vector3f& p : b.positions) points.push_back(p.cast<double>());
  Similarity3 seed;
  seed.rotation = track_a_from_b.rotation;
  seed.translation = track_a_from_b.translation;
  const StructureRegistration reg =
      RegisterStructure(points, map, seed, Eigen::Vector3d::UnitX(), r);
  step.inlier_share = reg.inlier_share;
  step.rms_m = reg.rms_m;
  step.track_m = track_a_from_b.translation.norm();
  if (!reg.success) {
    step.message = "not registered: " + reg.message;
  } else if (reg.inlier_share < options.min_inlier_share) {
    step.message = fmt::format(
        "not registered: {:.0f} % of the points on the other scan's "
        "surfaces (< {:.0f} %)",
        100.0 * reg.inlier_share, 100.0 * options.min_inlier_share);
  } else {
    step.registered = true;
  }
  *lidar_a_from_b = Rigid3d(reg.map_from_world.rotation, reg.map_from_world.translation);
  if (!step.registered) return step;
  const Eigen::Vector3d t_lidar = lidar_a_from_b->translation;
  const Eigen::Vector3d t_track = track_a_from_b.translation;
  step.lidar_m = t_lidar.norm();
  const auto [el_lidar, az_lidar] = ElevationAzimuth(t_lidar);
  const auto [el_track, az_track] = ElevationAzimuth(t_track);
  step.pitch_deg = (el_track - el_lidar) * kRadToDeg;
  step.heading_deg = WrapDeg((az_track - az_lidar) * kRadToDeg);
  step.turn_difference_deg =
      RotationDifferenceDeg(track_a_from_b.rotation, lidar_a_from_b->rotation);
  // The track's rotation relative to the scans', in the earlier scan's frame: its component
  // about the up axis is the difference of the two turns (to first order in the small tilts).
  const Eigen::AngleAxisd difference(track_a_from_b.rotation * lidar_a_from_b->rotation.inverse());
  step.yaw_difference_deg = difference.angle() * difference.axis().z() * kRadToDeg;
  return step;
}

}  // namespace

void LidarTrackOptions::Check() const {
  EPILOC_CHECK(std::isfinite(min_range_m) && min_range_m >= 0,
               "lidar track: min_range_m must be >= 0, got {}", min_range_m);
  EPILOC_CHECK(std::isfinite(max_range_m) && max_range_m > min_range_m,
               "lidar track: max_range_m must exceed min_range_m, got {}", max_range_m);
  EPILOC_CHECK(std::isfinite(voxel_m) && voxel_m >= 0, "lidar track: voxel_m must be >= 0, got {}",
               voxel_m);
  EPILOC_CHECK(!max_distances_m.empty(), "lidar track: no correspondence distance");
  EPILOC_CHECK(std::isfinite(min_inlier_share) && min_inlier_share >= 0 && min_inlier_share <= 1,
               "lidar track: min_inlier_share must be in [0, 1], got {}", min_inlier_share);
  EPILOC_CHECK(num_threads >= 1, "lidar track: num_threads must be >= 1, got {}", num_threads);
}

LidarTrack EstimateLidarTrack(const Drive& drive,
                              const EnuFrame& map_frame,
                              const LidarTrackOptions& options,
                              const ProgressCallback& progress) {
  options.Check();
  const size_t n = drive.lidar.size();
  if (n < 2) Throw("{}: the LiDAR track needs at least two scans, the drive has {}", drive.dir, n);
  std::vector<Rigid3d> map_from_sensor(n);
  for (size_t i = 0; i < n; ++i) {
    map_from_sensor[i] = anchor_internal::MapFromSample(map_frame, drive.lidar[i].sensor_position,
                                                        drive.lidar[i].enu_from_sensor);
  }

  LidarTrack out;
  out.steps.resize(n - 1);
  std::vector<Rigid3d> lidar_steps(n - 1);
  std::atomic<int64_t> done{0};
  std::mutex progress_mutex;
  ParallelFor(static_cast<int64_t>(n - 1), options.num_threads, [&](int64_t i) {
    const Rigid3d track_a_from_b = map_from_sensor[i].Inverse() * map_from_sensor[i + 1];
    // Each pair reads its own two scans (each scan is read twice): memory stays bounded on a
    // long drive.
    const PointCloud a = ReadThinnedScan(drive, drive.lidar[i], options);
    const PointCloud b = ReadThinnedScan(drive, drive.lidar[i + 1], options);
    out.steps[i] = RegisterPair(a, b, track_a_from_b, options, &lidar_steps[i]);
    out.steps[i].from_scan = drive.lidar[i].scan;
    out.steps[i].to_scan = drive.lidar[i + 1].scan;
    const int64_t d = ++done;
    if (progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      progress(d, static_cast<int64_t>(n - 1));
    }
  });

  // The path: registered steps turned by the track's attitude at the earlier scan.
  std::vector<Eigen::Vector3d> path(n, Eigen::Vector3d::Zero());
  std::vector<double> pitches, headings;
  out.cumulative_yaw_deg.assign(n, 0.0);
  for (size_t i = 0; i + 1 < n; ++i) {
    out.cumulative_yaw_deg[i + 1] =
        out.cumulative_yaw_deg[i] +
        (out.steps[i].registered ? out.steps[i].yaw_difference_deg : 0.0);
    out.max_abs_cumulative_yaw_deg =
        std::max(out.max_abs_cumulative_yaw_deg, std::abs(out.cumulative_yaw_deg[i + 1]));
    const LidarTrackStep& s = out.steps[i];
    const Eigen::Vector3d track_step =
        map_from_sensor[i + 1].translation - map_from_sensor[i].translation;
    path[i + 1] = path[i] + (s.registered ? map_from_sensor[i].rotation * lidar_steps[i].translation
                                          : track_step);
    if (!s.registered) continue;
    ++out.num_registered;
    out.lidar_length_m += s.lidar_m;
    out.track_length_m += s.track_m;
    out.max_turn_difference_deg = std::max(out.max_turn_difference_deg, s.turn_difference_deg);
    if (s.lidar_m > 0.5) {
      pitches.push_back(s.pitch_deg);
      headings.push_back(s.heading_deg);
      out.max_abs_pitch_deg = std::max(out.max_abs_pitch_deg, std::abs(s.pitch_deg));
      out.max_abs_heading_deg = std::max(out.max_abs_heading_deg, std::abs(s.heading_deg));
    }
  }
  out.median_pitch_deg = Median(pitches);
  out.median_heading_deg = Median(headings);
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) offset += map_from_sensor[i].translation - path[i];
  offset /= static_cast<double>(n);
  for (size_t i = 0; i < n; ++i) {
    out.scans.push_back(drive.lidar[i].scan);
    out.timestamps_s.push_back(drive.lidar[i].timestamp_s);
    out.correction_m.push_back(path[i] + offset - map_from_sensor[i].translation);
    out.max_correction_m = std::max(out.max_correction_m, out.correction_m.back().norm());
  }
  return out;
}

Drive CorrectDriveTrack(const Drive& drive, const EnuFrame& map_frame, const LidarTrack& track) {
  if (track.scans.empty() || track.correction_m.size() != track.scans.size() ||
      track.timestamps_s.size() != track.scans.size()) {
    Throw("{}: the LiDAR track given is empty or malformed", drive.dir);
  }
  // Each of the drive's scans by its number (another camera's import of the same recording may
  // hold a part of them).
  std::unordered_map<int64_t, size_t> track_index;
  for (size_t j = 0; j < track.scans.size(); ++j) track_index.emplace(track.scans[j], j);
  std::vector<size_t> index_of(drive.lidar.size());
  for (size_t i = 0; i < drive.lidar.size(); ++i) {
    const auto it = track_index.find(drive.lidar[i].scan);
    if (it == track_index.end()) {
      Throw("{}: scan {} is not in the LiDAR track given (not this recording's track?)", drive.dir,
            drive.lidar[i].scan);
    }
    const size_t j = it->second;
    if (std::abs(track.timestamps_s[j] - drive.lidar[i].timestamp_s) > 1e-6) {
      Throw("{}: scan {} was taken at {:.6f} s, the LiDAR track's at {:.6f} s", drive.dir,
            drive.lidar[i].scan, drive.lidar[i].timestamp_s, track.timestamps_s[j]);
    }
    index_of[i] = j;
  }
  const auto move = [&](const Geodetic& at, const Eigen::Vector3d& by) {
    return map_frame.ToGeodetic(map_frame.ToEnu(at) + by);
  };
  // The correction at time t: linear between the scans, held beyond the first and the last.
  const auto correction_at = [&](double t) -> Eigen::Vector3d {
    const auto& ts = track.timestamps_s;
    if (t <= ts.front()) return track.correction_m.front();
    if (t >= ts.back()) return track.correction_m.back();
    const size_t j = static_cast<size_t>(std::upper_bound(ts.begin(), ts.end(), t) - ts.begin());
    const double span = ts[j] - ts[j - 1];
    const double a = span > 0 ? (t - ts[j - 1]) / span : 0.0;
    return (1.0 - a) * track.correction_m[j - 1] + a * track.correction_m[j];
  };
  Drive out = drive;
  for (size_t i = 0; i < drive.lidar.size(); ++i) {
    out.lidar[i].sensor_position =
        move(drive.lidar[i].sensor_position, track.correction_m[index_of[i]]);
  }
  if (out.ground_truth) {
    for (PositionSample& s : out.ground_truth->samples) {
      s.position = move(s.position, correction_at(s.timestamp_s));
    }
  }
  return out;
}

}  // namespace epiloc
