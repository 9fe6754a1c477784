// AnchorDrive: the map opened with bounded memory, sanity checks of its frame against the drive,
// and the selected frames anchored in parallel.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>

#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include "anchor_internal.h"
#include "epiloc/anchor/anchor.h"
#include "epiloc/camera/undistorter.h"
#include "epiloc/cloud/tiled_cloud.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "epiloc/io/frame_reader.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// OpenCV's own worker threads off while frames run in parallel; restored on exit.
class OpenCvThreadsGuard {
 public:
  explicit OpenCvThreadsGuard(int threads) : saved_(cv::getNumThreads()) {
    cv::setNumThreads(threads);
  }
  ~OpenCvThreadsGuard() { cv::setNumThreads(saved_); }
  OpenCvThreadsGuard(const OpenCvThreadsGuard&) = delete;
  OpenCvThreadsGuard& operator=(const OpenCvThreadsGuard&) = delete;

 private:
  int saved_;
};

}  // namespace

namespace anchor_internal {

std::vector<size_t> SelectFrames(const AnchorInputs& inputs, const Drive& drive) {
  std::vector<size_t> indices;
  if (inputs.frames.empty()) {
    for (size_t i = 0; i < drive.frames.size(); i += inputs.every) indices.push_back(i);
    return indices;
  }
  std::map<frame_t, size_t> by_number;
  for (size_t i = 0; i < drive.frames.size(); ++i) by_number[drive.frames[i].frame] = i;
  for (const frame_t f : inputs.frames) {
    const auto it = by_number.find(f);
    if (it == by_number.end()) Throw("{}: frame {} is not in the drive", drive.dir, f);
    indices.push_back(it->second);
  }
  std::sort(indices.begin(), indices.end());
  indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
  return indices;
}


std::unique_ptr<TiledCloud> OpenMap(const std::string& path,
                                    const std::string& tile_dir_option,
                                    int64_t max_whole_points) {
  std::error_code error;
  if (fs::is_directory(path, error)) return std::make_unique<TiledCloud>(path);
  if (!fs::exists(path, error)) Throw("{}: no such point-cloud file", path);
  const PointCloudInfo info = ReadPointCloudHeader(path);
  if (info.num_points >= 0 && info.num_points <= max_whole_points) {
    return std::make_unique<TiledCloud>(path);
  }
  const std::string tile_dir = tile_dir_option.empty() ? path + ".tiles" : tile_dir_option;
  const fs::path index = fs::path(tile_dir) / "tiles.json";
  if (!fs::exists(index, error) || fs::last_write_time(index) < fs::last_write_time(path)) {
    spdlog::info("{}: {} points, cutting it into tiles in {} (once)", path, info.num_points,
                 tile_dir);
    TileOptions tile_options;
    tile_options.overwrite = true;
    BuildTiledCloud(path, tile_dir, tile_options);
  }
  return std::make_unique<TiledCloud>(tile_dir);
}

void CheckMapNearDrive(const std::string& cloud_path,
                       const TiledCloud& map,
                       const EnuFrame& map_frame,
                       const Drive& drive,
                       double max_distance_m) {
  if (map.bounds().Empty()) Throw("{}: the point cloud has no points", cloud_path);
  const PositionTrack& track =
      drive.gnss.samples.empty() && drive.ground_truth ? *drive.ground_truth : drive.gnss;
  if (track.samples.empty()) return;
  const Bounds3f& b = map.bounds();
  double nearest = INFINITY;
  for (const PositionSample& s : track.samples) {
    const Eigen::Vector3d p = map_frame.ToEnu(s.position);
    const double dx = std::max({0.0, b.min.x() - p.x(), p.x() - b.max.x()});
    const double dy = std::max({0.0, b.min.y() - p.y(), p.y() - b.max.y()});
    nearest = std::min(nearest, std::hypot(dx, dy));
  }
  if (nearest > max_distance_m) {
    Throw(
        "{}: the cloud (x {:.0f}..{:.0f}, y {:.0f}..{:.0f} m about {:.6f},{:.6f}) lies {:.1f} km "
        "from every position of drive {}: it is in another frame (wrong --cloud-origin, "
        "sidecar or map?)",
        cloud_path, b.min.x(), b.max.x(), b.min.y(), b.max.y(), map_frame.origin().lat_deg,
        map_frame.origin().lon_deg, nearest / 1000.0, drive.dir);
  }
}

}  // namespace anchor_internal

void AnchorInputs::Check() const {
  EPILOC_CHECK(!cloud_path.empty(), "--cloud is required");
  EPILOC_CHECK(!drive_dir.empty(), "--drive is required");
  CheckGeodetic(map_origin, "map origin");
  photos.Check();
  EPILOC_CHECK(every >= 1, "--every must be >= 1, got {}", every);
  EPILOC_CHECK(max_whole_points >= 0, "anchor inputs: max_whole_points must be >= 0");
  EPILOC_CHECK(std::isfinite(max_map_distance_m) && max_map_distance_m > 0,
               "anchor inputs: max_map_distance_m must be > 0");
}

AnchorDriveResult AnchorDrive(const AnchorInputs& inputs,
                              const AnchorOptions& options,
                              const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  inputs.Check();
  options.Check();
  const Drive drive = LoadDrive(inputs.drive_dir);
  if (drive.gnss.samples.empty()) {
    Throw("{}: the drive has no GNSS positions to anchor from", inputs.drive_dir);
  }
  const std::vector<size_t> indices = anchor_internal::SelectFrames(inputs, drive);
  const std::unique_ptr<TiledCloud> map =
      anchor_internal::OpenMap(inputs.cloud_path, inputs.tile_dir, inputs.max_whole_points);
  const EnuFrame map_frame(inputs.map_origin);
  anchor_internal::CheckMapNearDrive(inputs.cloud_path, *map, map_frame, drive,
                                     inputs.max_map_distance_m);
  if (options.render.shading == RenderShading::kColour && !map->has_colour()) {
    Throw("{}: --shading colour needs a coloured map (build-map --colorize)", inputs.cloud_path);
  }
  if (options.render.shading == RenderShading::kIntensity && !map->has_intensity()) {
    Throw("{}: --shading intensity needs a map with intensity", inputs.cloud_path);
  }
  std::unique_ptr<MapPhotos> photos;
  if (!inputs.photos_dir.empty()) {
    photos = std::make_unique<MapPhotos>(inputs.photos_dir, map_frame, inputs.photos);
    spdlog::info("matching against {} posed map photographs of {}", photos->size(),
                 inputs.photos_dir);
  }
  const Undistorter undistorter(drive.camera);
  const Camera& camera = undistorter.undistorted_camera();
  const FrameReader reader(drive);

  AnchorDriveResult out;
  out.drive_name = drive.name;
  out.frames.resize(indices.size());
  const OpenCvThreadsGuard opencv_threads(options.num_threads > 1 ? 1 : cv::getNumThreads());
  std::mutex progress_mutex;
  int64_t done = 0;
  ParallelFor(static_cast<int>(indices.size()), options.num_threads, [&](int64_t k64) {
    const int k = static_cast<int>(k64);
    const FrameRecord& record = drive.frames[indices[k]];
    const cv::Mat image = undistorter.Undistort(reader.ReadColour(indices[k]));
    const auto gnss = drive.gnss.Interpolate(record.timestamp_s, drive.max_gap_s);
    AnchorResult result;
    result.frame = record.frame;
    result.timestamp_s = record.timestamp_s;
    if (!gnss) {
      result.status = AnchorStatus::kNoPrior;
      result.message = fmt::format("no GNSS position within {} s", drive.max_gap_s);
    } else {
      const PointCloud local = map->Load(map_frame.ToEnu(gnss->position), options.load_radius_m);
      auto prior = MakePosePrior(drive.gnss, map_frame, local, record.frame, record.timestamp_s,
                                 drive.max_gap_s, options.prior);
      if (!prior) {
        result.status = AnchorStatus::kNoPrior;
        result.message = "no heading: the GNSS track does not move around the frame time";
      } else {
        if (options.heading_error_deg > 0) {
          std::mt19937_64 rng(options.seed * 7919ULL + static_cast<uint64_t>(record.frame));
          prior = RotatePriorHeading(*prior, std::uniform_real_distribution<double>(
                                                 -options.heading_error_deg,
                                                 options.heading_error_deg)(rng));
        }
        result = AnchorFrame(image, camera, local, map_frame, *prior, options, photos.get());
      }
    }
    out.frames[k] = std::move(result);
    std::lock_guard<std::mutex> lock(progress_mutex);
    ++done;
    if (progress) progress(done, static_cast<int64_t>(indices.size()));
  });
  for (const AnchorResult& r : out.frames) out.num_ok += r.status == AnchorStatus::kOk ? 1 : 0;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace epiloc
