#include "epiloc/anchor/build_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include <spdlog/spdlog.h>
#include <Eigen/Eigenvalues>

#include "anchor_internal.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/voxel.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"

namespace epiloc {
namespace {

using anchor_internal::MapFromSample;
using anchor_internal::ScanFormat;

// Motion compensation of one scan (BuildMapOptions::deskew_period_s): the sensor's motion
// relative to its pose at the scan time, at the start and end of the revolution, interpolated
// linearly in time (constant velocity over one revolution).
class Deskew {
 public:
  Deskew(const Rigid3d& before, const Rigid3d& after, bool clockwise)
      : before_(before), after_(after), clockwise_(clockwise) {}

  // The point (sensor frame at its measurement time) in the sensor frame at the scan time.
  Eigen::Vector3f Apply(const Eigen::Vector3f& p) const {
    const double phi = std::atan2(p.y(), p.x());
    const double fraction = (clockwise_ ? -phi : phi) / M_PI;  // tau / half period, [-1, 1]
    const Rigid3d& end = fraction >= 0 ? after_ : before_;
    const double a = std::abs(fraction);
    const Eigen::Quaterniond q = Eigen::Quaterniond::Identity().slerp(a, end.rotation);
    return (q * p.cast<double>() + a * end.translation).cast<float>();
  }

 private:
  Rigid3d before_, after_;  // sensor_at_scan_time_from_sensor at -+ half a period
  bool clockwise_;
};

std::optional<Deskew> MakeDeskew(const Drive& drive,
                                 const LidarScan& scan,
                                 const EnuFrame& map_frame,
                                 const Rigid3d& map_from_sensor,
                                 const BuildMapOptions& options) {
  if (options.deskew_period_s <= 0) return std::nullopt;
  const PositionTrack* track = anchor_internal::OrientedTrack(drive);
  if (!track) {
    Throw("{}: deskewing needs camera orientations in the ground truth or GNSS", drive.dir);
  }
  const double half = 0.5 * options.deskew_period_s;
  const auto pose_at = [&](double t) -> std::optional<Rigid3d> {
    const auto s = track->Interpolate(t, std::max(drive.max_gap_s, 1.0));
    if (!s) return std::nullopt;
    return MapFromSample(map_frame, s->position, *s->enu_from_cam);
  };
  const auto at_scan = pose_at(scan.timestamp_s);
  const auto before = pose_at(scan.timestamp_s - half);
  const auto after = pose_at(scan.timestamp_s + half);
  if (!at_scan || !before || !after) {
    spdlog::warn("{}: no camera pose around scan {}; not deskewed", drive.dir, scan.scan);
    return std::nullopt;
  }
  // sensor(t_scan)_from_sensor(t) = sensor_from_map(t_scan) * map_from_cam(t) * cam_from_sensor.
  const Rigid3d cam_from_sensor = at_scan->Inverse() * map_from_sensor;
  const Rigid3d sensor_from_map = map_from_sensor.Inverse();
  return Deskew(sensor_from_map * *before * cam_from_sensor,
                sensor_from_map * *after * cam_from_sensor, options.spin_clockwise);
}

// The scan's points within the range limits, moved into the map frame.
PointCloud ReadScanInMap(const Drive& drive,
                         const LidarScan& scan,
                         const EnuFrame& map_frame,
                         const BuildMapOptions& options) {
  // A scan's own colours are not the map's.
  const PointCloud raw =
      anchor_internal::ReadScanInRange(drive, scan, options.min_range_m, options.max_range_m, true);
  const Rigid3d map_from_sensor = MapFromSample(map_frame, scan.sensor_position,
                                                scan.enu_from_sensor);
  const Eigen::Matrix3f r = map_from_sensor.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3d t = map_from_sensor.translation;
  const std::optional<Deskew> deskew = MakeDeskew(drive, scan, map_frame, map_from_sensor, options);
  PointCloud out;
  out.Reserve(raw.size(), raw.HasIntensity(), false);
  for (size_t i = 0; i < raw.size(); ++i) {
    Eigen::Vector3f p = raw.positions[i];
    if (deskew) p = deskew->Apply(p);
    // Rotate in float, translate in double: map coordinates may be far from the origin.
    out.positions.push_back((t + (r * p).cast<double>()).cast<float>());
    if (raw.HasIntensity()) out.intensity.push_back(raw.intensity[i]);
  }
  return out;
}

// CheckTrackScale for one stretch: the scans (map frame) each moved by stretch * its offset, the
// mean thickness (sqrt of the smallest covariance eigenvalue) of the cells of side cell_m that
// hold at least min_points points of two or more scans, and their number (INFINITY, 0: none).
std::pair<double, int64_t> SharedSurfaceThickness(const std::vector<PointCloud>& scans,
                                                  const std::vector<Eigen::Vector3d>& offsets,
                                                  const Eigen::Vector3d& origin,
                                                  double stretch,
                                                  size_t stride,
                                                  double cell_m,
                                                  int64_t min_points) {
  struct Cell {
    int scan = -1;        // the first scan with a point here
    bool shared = false;  // points of another scan too
    int64_t n = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d sum2 = Eigen::Matrix3d::Zero();
  };
  std::unordered_map<uint64_t, Cell> cells;
  const double inverse = 1.0 / cell_m;
  for (size_t i = 0; i < scans.size(); ++i) {
    const Eigen::Vector3d shift = stretch * offsets[i] - origin;  // coordinates about the origin
    for (size_t j = 0; j < scans[i].size(); j += stride) {
      const Eigen::Vector3d x = scans[i].positions[j].cast<double>() + shift;
      // 21 bits per axis: +-2^20 cells about the origin, beyond any one drive's map.
      uint64_t key = 0;
      for (int a = 0; a < 3; ++a) {
        const int64_t c = static_cast<int64_t>(std::floor(x[a] * inverse)) + (int64_t{1} << 20);
        key = (key << 21) | (static_cast<uint64_t>(c) & ((uint64_t{1} << 21) - 1));
      }
      Cell& cell = cells[key];
      if (cell.scan < 0) cell.scan = static_cast<int>(i);
      cell.shared |= cell.scan != static_cast<int>(i);
      ++cell.n;
      cell.sum += x;
      cell.sum2 += x * x.transpose();
    }
  }
  double thickness = 0.0;
  int64_t shared = 0;
  for (const auto& [key, cell] : cells) {
    if (!cell.shared || cell.n < min_points) continue;
    const Eigen::Vector3d mean = cell.sum / static_cast<double>(cell.n);
    const Eigen::Matrix3d covariance =
        cell.sum2 / static_cast<double>(cell.n) - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
    eigen.computeDirect(covariance, Eigen::EigenvaluesOnly);
    thickness += std::sqrt(std::max(eigen.eigenvalues()[0], 0.0));
    ++shared;
  }
  return {shared > 0 ? thickness / static_cast<double>(shared) : INFINITY, shared};
}

// The first position of the drive: ground truth, else GNSS, else the first scan.
std::pair<Geodetic, std::string> DriveOrigin(const Drive& drive) {
  if (drive.ground_truth && !drive.ground_truth->samples.empty()) {
    return {drive.ground_truth->samples.front().position,
            "first ground-truth position of drive " + drive.name};
  }
  if (!drive.gnss.samples.empty()) {
    return {drive.gnss.samples.front().position, "first GNSS position of drive " + drive.name};
  }
  if (!drive.lidar.empty()) {
    return {drive.lidar.front().sensor_position, "first scan position of drive " + drive.name};
  }
  Throw("{}: the drive has no positions to place a map origin at", drive.dir);
}

}  // namespace

std::string ColourModeName(ColourMode mode) {
  return mode == ColourMode::kAverage ? "average" : "closest";
}

ColourMode ParseColourMode(const std::string& name) {
  if (name == "average") return ColourMode::kAverage;
  if (name == "closest") return ColourMode::kClosest;
  Throw("unknown colour mode '{}' (known: average, closest)", name);
}

void MapColourOptions::Check() const {
  EPILOC_CHECK(frame_step >= 1, "colour options: frame_step must be >= 1, got {}", frame_step);
  EPILOC_CHECK(std::isfinite(min_range_m) && min_range_m >= 0 && std::isfinite(max_range_m) &&
                   max_range_m > min_range_m,
               "colour options: need 0 <= min_range_m < max_range_m, got {} and {}", min_range_m,
               max_range_m);
  EPILOC_CHECK(std::isfinite(occlusion_rel) && occlusion_rel >= 0,
               "colour options: occlusion_rel must be >= 0, got {}", occlusion_rel);
  EPILOC_CHECK(std::isfinite(occlusion_abs_m) && occlusion_abs_m >= 0,
               "colour options: occlusion_abs_m must be >= 0, got {}", occlusion_abs_m);
  EPILOC_CHECK(border_px >= 0, "colour options: border_px must be >= 0, got {}", border_px);
  EPILOC_CHECK(std::isfinite(footprint_m) && footprint_m >= 0,
               "colour options: footprint_m must be >= 0, got {}", footprint_m);
  render.Check();
}

void BuildMapOptions::Check() const {
  EPILOC_CHECK(std::isfinite(voxel_m) && voxel_m >= 0, "--voxel must be >= 0 m, got {}", voxel_m);
  EPILOC_CHECK(std::isfinite(min_range_m) && min_range_m >= 0,
               "build-map options: min_range_m must be >= 0, got {}", min_range_m);
  EPILOC_CHECK(std::isfinite(max_range_m) && max_range_m > min_range_m,
               "build-map options: max_range_m must exceed min_range_m, got {}", max_range_m);
  EPILOC_CHECK(std::isfinite(deskew_period_s) && deskew_period_s >= 0 && deskew_period_s < 10,
               "--deskew-period must be in [0, 10) s, got {}", deskew_period_s);
  EPILOC_CHECK(num_threads >= 1, "build-map options: num_threads must be >= 1, got {}",
               num_threads);
  colour.Check();
}

PointCloud MergeScans(const Drive& drive,
                      const EnuFrame& map_frame,
                      const BuildMapOptions& options,
                      const ProgressCallback& progress,
                      BuildMapSummary* summary) {
  options.Check();
  if (drive.lidar.empty()) Throw("{}: the drive has no LiDAR scans (drive.json 'lidar')", drive.dir);
  const int num_scans = static_cast<int>(drive.lidar.size());
  std::optional<VoxelGrid> grid;
  if (options.voxel_m > 0) grid.emplace(options.voxel_m);
  PointCloud merged;
  int64_t points_in = 0;
  // Scans are read in parallel in batches and added in scan order, so the result is the same for
  // any thread count.
  const int batch = std::max(1, options.num_threads);
  std::vector<PointCloud> scans(batch);
  for (int first = 0; first < num_scans; first += batch) {
    const int n = std::min(batch, num_scans - first);
    ParallelFor(n, options.num_threads, [&](int64_t i64) {
      const int i = static_cast<int>(i64);
      scans[i] = ReadScanInMap(drive, drive.lidar[first + i], map_frame, options);
    });
    for (int i = 0; i < n; ++i) {
      points_in += static_cast<int64_t>(scans[i].size());
      if (grid) {
        grid->Add(scans[i]);
      } else {
        merged.Append(scans[i]);
      }
      scans[i] = PointCloud();
    }
    if (progress) progress(first + n, num_scans);
  }
  if (grid) merged = grid->Extract();
  if (summary) {
    summary->num_scans = num_scans;
    summary->num_points_in = points_in;
  }
  return merged;
}

TrackScaleCheck CheckTrackScale(const Drive& drive,
                                const EnuFrame& map_frame,
                                const BuildMapOptions& options,
                                double max_stretch,
                                double step,
                                int64_t max_points) {
  options.Check();
  EPILOC_CHECK(std::isfinite(max_stretch) && max_stretch > 0 && max_stretch < 0.5,
               "track scale check: max_stretch must be in (0, 0.5), got {}", max_stretch);
  EPILOC_CHECK(std::isfinite(step) && step > 0 && step <= max_stretch,
               "track scale check: step must be in (0, max_stretch], got {}", step);
  EPILOC_CHECK(max_points >= 1, "track scale check: max_points must be >= 1, got {}", max_points);
  if (drive.lidar.empty())
    Throw("{}: the drive has no LiDAR scans (drive.json 'lidar')", drive.dir);
  TrackScaleCheck out;
  // Cells of a surface patch: several scan lines of each scan, flat enough to be a plane.
  constexpr double kCellM = 0.5;
  constexpr int64_t kMinCellPoints = 10;
  out.voxel_m = kCellM;
  out.num_scans = static_cast<int64_t>(drive.lidar.size());
  // Each scan's points in the map frame and its horizontal offset from the first scan.
  std::vector<PointCloud> scans(drive.lidar.size());
  ParallelFor(out.num_scans, options.num_threads, [&](int64_t i) {
    scans[i] = ReadScanInMap(drive, drive.lidar[i], map_frame, options);
    scans[i].intensity.clear();
  });
  int64_t total = 0;
  for (const PointCloud& c : scans) total += static_cast<int64_t>(c.size());
  const int64_t stride = std::max<int64_t>(1, (total + max_points - 1) / max_points);
  const Eigen::Vector3d first = map_frame.ToEnu(drive.lidar.front().sensor_position);
  std::vector<Eigen::Vector3d> offsets(drive.lidar.size());
  for (size_t i = 0; i < drive.lidar.size(); ++i) {
    Eigen::Vector3d d = map_frame.ToEnu(drive.lidar[i].sensor_position) - first;
    d.z() = 0.0;
    offsets[i] = d;
    out.span_m = std::max(out.span_m, d.norm());
    out.num_points += (static_cast<int64_t>(scans[i].size()) + stride - 1) / stride;
  }
  const int n = static_cast<int>(std::lround(max_stretch / step));
  for (int k = -n; k <= n; ++k) out.factors.push_back(1.0 + k * step);
  out.thickness_m.assign(out.factors.size(), 0.0);
  out.shared_voxels.assign(out.factors.size(), 0);
  ParallelFor(static_cast<int64_t>(out.factors.size()), options.num_threads, [&](int64_t f) {
    std::tie(out.thickness_m[f], out.shared_voxels[f]) =
        SharedSurfaceThickness(scans, offsets, first, out.factors[f] - 1.0,
                               static_cast<size_t>(stride), kCellM, kMinCellPoints);
  });
  const size_t best = static_cast<size_t>(
      std::min_element(out.thickness_m.begin(), out.thickness_m.end()) - out.thickness_m.begin());
  out.best_factor = out.factors[best];
  if (best > 0 && best + 1 < out.factors.size()) {
    const double a = out.thickness_m[best - 1];
    const double b = out.thickness_m[best];
    const double c = out.thickness_m[best + 1];
    const double curvature = a - 2.0 * b + c;
    if (curvature > 0) out.best_factor += 0.5 * step * (a - c) / curvature;
  }
  return out;
}

BuildMapSummary BuildMap(const std::string& drive_dir,
                         const std::string& out_path,
                         const std::optional<Geodetic>& origin,
                         const std::string& origin_source,
                         const BuildMapOptions& options,
                         const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  const Drive drive = LoadDrive(drive_dir);
  if (drive.lidar.empty()) Throw("{}: the drive has no LiDAR scans (drive.json 'lidar')", drive_dir);
  CloudWriteOptions write_options;
  write_options.Check();
  CloudFormatFromPath(out_path);  // an unknown extension fails before the work

  BuildMapSummary summary;
  summary.drive_name = drive.name;
  std::string source = origin_source;
  if (origin) {
    summary.enu_origin = *origin;
  } else {
    std::tie(summary.enu_origin, source) = DriveOrigin(drive);
  }
  const EnuFrame map_frame(summary.enu_origin);

  const int64_t num_scans = static_cast<int64_t>(drive.lidar.size());
  const int64_t num_frames =
      options.colorize
          ? (static_cast<int64_t>(drive.frames.size()) + options.colour.frame_step - 1) /
                options.colour.frame_step
          : 0;
  const int64_t total = num_scans + num_frames;
  PointCloud cloud = MergeScans(
      drive, map_frame, options,
      [&](int64_t done, int64_t) {
        if (progress) progress(done, total);
      },
      &summary);
  if (options.colorize) {
    ColorizeCloud(
        drive, map_frame, options.colour, options.num_threads, &cloud,
        [&](int64_t done, int64_t) {
          if (progress) progress(num_scans + done, total);
        },
        &summary);
  }
  if (cloud.empty()) Throw("{}: no scan point within the range limits; the map is empty", drive_dir);

  const auto parent = std::filesystem::path(out_path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent);
  WritePointCloud(out_path, cloud, write_options);

  summary.num_points_out = static_cast<int64_t>(cloud.size());
  MapSidecar sidecar = DescribeCloud(cloud, summary.enu_origin, source);
  summary.bounds = sidecar.bounds;
  sidecar.source_drive = drive.name;
  sidecar.source_dir = std::filesystem::absolute(drive.dir).lexically_normal().string();
  sidecar.voxel_m = options.voxel_m;
  sidecar.num_scans = summary.num_scans;
  if (options.colorize) {
    sidecar.colour_mode = ColourModeName(options.colour.mode);
    sidecar.colour_frames = summary.num_colour_frames;
    sidecar.coloured_points = summary.num_coloured_points;
  }
  WriteMapSidecar(sidecar, SidecarPath(out_path));
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

namespace anchor_internal {

CloudFormat ScanFormat(const LidarScan& scan, const std::string& path) {
  if (scan.format == "kitti_bin") return CloudFormat::kKittiBin;
  try {
    return ParseCloudFormat(scan.format);
  } catch (const Error& e) {
    Throw("{}: scan format '{}': {}", path, scan.format, e.what());
  }
}

PointCloud ReadScanInRange(const Drive& drive,
                           const LidarScan& scan,
                           double min_range_m,
                           double max_range_m,
                           bool with_intensity) {
  const std::string path = drive.ScanPath(scan);
  CloudReadOptions read;
  read.format = ScanFormat(scan, path);
  read.read_intensity = with_intensity;
  read.read_colour = false;
  const PointCloud raw = ReadPointCloud(path, read);
  const bool intensity = with_intensity && raw.HasIntensity();
  const float min2 = static_cast<float>(min_range_m * min_range_m);
  const float max2 = static_cast<float>(max_range_m * max_range_m);
  PointCloud kept;
  kept.Reserve(raw.size(), intensity, false);
  for (size_t i = 0; i < raw.size(); ++i) {
    const float range2 = raw.positions[i].squaredNorm();
    if (range2 < min2 || range2 > max2) continue;
    kept.positions.push_back(raw.positions[i]);
    if (intensity) kept.intensity.push_back(raw.intensity[i]);
  }
  return kept;
}

}  // namespace anchor_internal
}  // namespace epiloc
