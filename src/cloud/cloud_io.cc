#include "epiloc/cloud/cloud_io.h"

#include <cmath>
#include <filesystem>

#include <spdlog/spdlog.h>

#include "cloud_io_internal.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr int64_t kReadBlock = 1 << 20;

void LogStats(const std::string& path, const CloudReadStats& stats) {
  if (stats.num_non_finite > 0) {
    spdlog::warn("{}: dropped {} of {} points with a non-finite x, y or z", path,
                 stats.num_non_finite, stats.num_records);
  }
  if (stats.num_intensity_clamped > 0) {
    spdlog::warn("{}: clamped {} intensities outside [0, 1] (see float_intensity_scale)", path,
                 stats.num_intensity_clamped);
  }
}

}  // namespace

std::string CloudFormatName(CloudFormat format) {
  switch (format) {
    case CloudFormat::kAuto:
      return "auto";
    case CloudFormat::kPly:
      return "ply";
    case CloudFormat::kPcd:
      return "pcd";
    case CloudFormat::kKittiBin:
      return "bin";
    case CloudFormat::kXyz:
      return "xyz";
    case CloudFormat::kLas:
      return "las";
  }
  return "?";
}

CloudFormat ParseCloudFormat(const std::string& name) {
  const std::string n = cloud_internal::ToLower(name);
  if (n == "auto") return CloudFormat::kAuto;
  if (n == "ply") return CloudFormat::kPly;
  if (n == "pcd") return CloudFormat::kPcd;
  if (n == "bin" || n == "kitti") return CloudFormat::kKittiBin;
  if (n == "xyz" || n == "txt") return CloudFormat::kXyz;
  if (n == "las") return CloudFormat::kLas;
  if (n == "laz") Throw("point-cloud format 'laz': compressed LAS is not supported");
  Throw("unknown point-cloud format '{}' (ply, pcd, bin, xyz, las)", name);
}

CloudFormat CloudFormatFromPath(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  if (!extension.empty()) extension = cloud_internal::ToLower(extension.substr(1));
  if (extension == "ply") return CloudFormat::kPly;
  if (extension == "pcd") return CloudFormat::kPcd;
  if (extension == "bin") return CloudFormat::kKittiBin;
  if (extension == "xyz" || extension == "txt") return CloudFormat::kXyz;
  if (extension == "las") return CloudFormat::kLas;
  if (extension == "laz") {
    Throw(
        "{}: LAZ (compressed LAS) is not supported: decompress it to .las (LAStools' laszip, "
        "PDAL) or convert it to .ply",
        path);
  }
  Throw("{}: unknown point-cloud file extension '{}' (ply, pcd, bin, xyz, txt, las)", path,
        extension);
}

void CloudReadOptions::Check() const {
  EPILOC_CHECK(std::isfinite(float_intensity_scale) && float_intensity_scale > 0,
               "CloudReadOptions: float_intensity_scale must be positive, got {}",
               float_intensity_scale);
}

void CloudWriteOptions::Check() const {
  EPILOC_CHECK(format != CloudFormat::kLas, "CloudWriteOptions: LAS cannot be written");
}

namespace cloud_internal {

std::unique_ptr<PointSource> OpenSource(const std::string& path, const CloudReadOptions& options) {
  options.Check();
  const CloudFormat format =
      options.format == CloudFormat::kAuto ? CloudFormatFromPath(path) : options.format;
  switch (format) {
    case CloudFormat::kPly:
      return OpenPlySource(path, options);
    case CloudFormat::kPcd:
      return OpenPcdSource(path, options);
    case CloudFormat::kKittiBin:
      return OpenKittiSource(path, options);
    case CloudFormat::kXyz:
      return OpenXyzSource(path, options);
    case CloudFormat::kLas:
      return OpenLasSource(path, options);
    case CloudFormat::kAuto:
      break;
  }
  Throw("{}: no reader for this format", path);
}

}  // namespace cloud_internal

PointCloudInfo ReadPointCloudHeader(const std::string& path, const CloudReadOptions& options) {
  return cloud_internal::OpenSource(path, options)->info();
}

PointCloud ReadPointCloud(const std::string& path,
                          const CloudReadOptions& options,
                          CloudReadStats* stats) {
  const auto source = cloud_internal::OpenSource(path, options);
  PointCloud cloud;
  if (source->reserve_hint() > 0) {
    cloud.Reserve(static_cast<size_t>(source->reserve_hint()), source->with_intensity(),
                  source->with_colour());
  }
  while (source->Read(kReadBlock, &cloud) > 0) {
  }
  LogStats(path, source->stats());
  if (stats != nullptr) *stats = source->stats();
  return cloud;
}

PointCloudReader::PointCloudReader(const std::string& path, const CloudReadOptions& options)
    : path_(path), source_(cloud_internal::OpenSource(path, options)) {}

PointCloudReader::~PointCloudReader() = default;
PointCloudReader::PointCloudReader(PointCloudReader&&) noexcept = default;
PointCloudReader& PointCloudReader::operator=(PointCloudReader&&) noexcept = default;

const PointCloudInfo& PointCloudReader::info() const { return source_->info(); }

const CloudReadStats& PointCloudReader::stats() const { return source_->stats(); }

bool PointCloudReader::ReadChunk(int64_t max_points, PointCloud* chunk) {
  EPILOC_CHECK(max_points > 0, "{}: chunk size must be positive, got {}", path_, max_points);
  chunk->positions.clear();
  chunk->intensity.clear();
  chunk->rgb.clear();
  while (static_cast<int64_t>(chunk->size()) < max_points) {
    if (source_->Read(max_points - static_cast<int64_t>(chunk->size()), chunk) == 0) {
      if (!finished_) LogStats(path_, source_->stats());
      finished_ = true;
      break;
    }
  }
  return !chunk->empty();
}

CloudReadStats ForEachPointChunk(const std::string& path,
                                 int64_t chunk_points,
                                 const std::function<void(const PointCloud& chunk)>& callback,
                                 const CloudReadOptions& options) {
  PointCloudReader reader(path, options);
  PointCloud chunk;
  while (reader.ReadChunk(chunk_points, &chunk)) callback(chunk);
  return reader.stats();
}

void WritePointCloud(const std::string& path,
                     const PointCloud& cloud,
                     const CloudWriteOptions& options) {
  options.Check();
  const CloudFormat format =
      options.format == CloudFormat::kAuto ? CloudFormatFromPath(path) : options.format;
  switch (format) {
    case CloudFormat::kPly:
      return cloud_internal::WritePly(path, cloud, options.binary);
    case CloudFormat::kPcd:
      return cloud_internal::WritePcd(path, cloud, options.binary);
    case CloudFormat::kKittiBin:
      return cloud_internal::WriteKittiBin(path, cloud);
    case CloudFormat::kXyz:
      return cloud_internal::WriteXyz(path, cloud);
    case CloudFormat::kLas:
    case CloudFormat::kAuto:
      break;
  }
  Throw("{}: cannot write point clouds as {}", path, CloudFormatName(format));
}

}  // namespace epiloc
