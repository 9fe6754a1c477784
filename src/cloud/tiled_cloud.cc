#include "epiloc/cloud/tiled_cloud.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "cloud_io_internal.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

Eigen::Vector3f VectorFromJson(const nlohmann::json& value, const std::string& where) {
  EPILOC_CHECK(value.is_array() && value.size() == 3, "{}: expected [x, y, z], got {}", where,
               value.dump());
  return Eigen::Vector3f(value[0].get<float>(), value[1].get<float>(), value[2].get<float>());
}

}  // namespace

void TiledCloudOptions::Check() const {
  EPILOC_CHECK(max_cached_points >= 0, "TiledCloudOptions: max_cached_points must be >= 0, got {}",
               max_cached_points);
  read_options.Check();
}

TiledCloud::TiledCloud(const std::string& path, const TiledCloudOptions& options)
    : options_(options) {
  options.Check();
  EPILOC_CHECK(fs::exists(path), "{}: does not exist", path);
  if (!fs::is_directory(path)) {
    // A plain cloud file: one tile, its cell the points' bounds.
    const PointCloud cloud = ReadPointCloud(path, options.read_options);
    single_file_ = true;
    num_points_ = static_cast<int64_t>(cloud.size());
    bounds_ = ComputeBounds(cloud);
    has_intensity_ = cloud.HasIntensity();
    has_colour_ = cloud.HasColour();
    if (!cloud.empty()) {
      TileInfo tile;
      tile.path = path;
      tile.num_points = num_points_;
      tile.bounds = bounds_;
      tile.cell_min_xy = bounds_.min.head<2>().cast<double>();
      tile.cell_max_xy = bounds_.max.head<2>().cast<double>();
      tiles_.push_back(tile);
      if (num_points_ <= options_.max_cached_points) {
        lru_.push_front(0);
        cache_[0] = CacheEntry{std::make_shared<const PointCloud>(cloud), lru_.begin()};
        cached_points_ = num_points_;
      }
    }
    num_tile_reads_ = 1;
    return;
  }
  const std::string index_path = (fs::path(path) / cloud_internal::kTileIndexName).string();
  std::ifstream in(index_path);
  if (!in) Throw("{}: cannot open (not a tile directory, or an unfinished build)", index_path);
  try {
    const nlohmann::json index = nlohmann::json::parse(in);
    if (index.value("format", "") != "epiloc-tiled-cloud") {
      Throw("{}: not an epiloc tiled-cloud index", index_path);
    }
    const int version = index.at("version").get<int>();
    EPILOC_CHECK(version == 1, "{}: tiled-cloud version {} is not supported (1)", index_path,
                 version);
    tile_size_m_ = index.at("tile_size_m").get<double>();
    EPILOC_CHECK(std::isfinite(tile_size_m_) && tile_size_m_ > 0, "{}: bad tile_size_m {}",
                 index_path, tile_size_m_);
    has_intensity_ = index.at("has_intensity").get<bool>();
    has_colour_ = index.at("has_colour").get<bool>();
    for (const nlohmann::json& entry : index.at("tiles")) {
      TileInfo tile;
      tile.ix = entry.at("ix").get<int32_t>();
      tile.iy = entry.at("iy").get<int32_t>();
      tile.path = (fs::path(path) / entry.at("file").get<std::string>()).string();
      tile.num_points = entry.at("num_points").get<int64_t>();
      tile.bounds.min = VectorFromJson(entry.at("min"), index_path);
      tile.bounds.max = VectorFromJson(entry.at("max"), index_path);
      tile.cell_min_xy = Eigen::Vector2d(tile.ix, tile.iy) * tile_size_m_;
      tile.cell_max_xy = Eigen::Vector2d(tile.ix + 1.0, tile.iy + 1.0) * tile_size_m_;
      EPILOC_CHECK(tile.num_points >= 0, "{}: tile {} {} has {} points", index_path, tile.ix,
                   tile.iy, tile.num_points);
      num_points_ += tile.num_points;
      if (tile.num_points > 0) {
        bounds_.Extend(tile.bounds.min);
        bounds_.Extend(tile.bounds.max);
      }
      tiles_.push_back(tile);
    }
  } catch (const nlohmann::json::exception& e) {
    Throw("{}: malformed tile index: {}", index_path, e.what());
  }
}

std::vector<size_t> TiledCloud::TilesNear(const Eigen::Vector3d& centre, double radius_m) const {
  EPILOC_CHECK(std::isfinite(radius_m) && radius_m >= 0, "TiledCloud: bad radius_m {}", radius_m);
  EPILOC_CHECK(centre.allFinite(), "TiledCloud: centre ({}, {}, {}) is not finite", centre.x(),
               centre.y(), centre.z());
  std::vector<size_t> near;
  const Eigen::Vector2d c = centre.head<2>();
  for (size_t t = 0; t < tiles_.size(); ++t) {
    // Distance from the centre to the nearest point of the cell rectangle.
    const Eigen::Vector2d nearest =
        c.cwiseMax(tiles_[t].cell_min_xy).cwiseMin(tiles_[t].cell_max_xy);
    if ((nearest - c).squaredNorm() <= radius_m * radius_m) near.push_back(t);
  }
  return near;
}

std::shared_ptr<const PointCloud> TiledCloud::GetTile(size_t index) {
  const auto hit = cache_.find(index);
  if (hit != cache_.end()) {
    lru_.splice(lru_.begin(), lru_, hit->second.position);
    return hit->second.cloud;
  }
  const TileInfo& tile = tiles_[index];
  auto cloud = std::make_shared<const PointCloud>(ReadPointCloud(tile.path, options_.read_options));
  ++num_tile_reads_;
  EPILOC_CHECK(static_cast<int64_t>(cloud->size()) == tile.num_points,
               "{}: has {} points, the tile index says {}", tile.path, cloud->size(),
               tile.num_points);
  EPILOC_CHECK(single_file_ ||
                   (cloud->HasIntensity() == has_intensity_ && cloud->HasColour() == has_colour_),
               "{}: its attributes differ from the tile index's", tile.path);
  lru_.push_front(index);
  cache_[index] = CacheEntry{cloud, lru_.begin()};
  cached_points_ += tile.num_points;
  while (cached_points_ > options_.max_cached_points && !lru_.empty()) {
    const size_t victim = lru_.back();
    lru_.pop_back();
    cached_points_ -= tiles_[victim].num_points;
    cache_.erase(victim);
  }
  return cloud;
}

PointCloud TiledCloud::Load(const Eigen::Vector3d& centre, double radius_m) {
  const std::vector<size_t> near = TilesNear(centre, radius_m);
  std::lock_guard<std::mutex> lock(mutex_);
  size_t total = 0;
  for (size_t t : near) total += static_cast<size_t>(tiles_[t].num_points);
  PointCloud out;
  out.Reserve(total, has_intensity_, has_colour_);
  for (size_t t : near) out.Append(*GetTile(t));
  return out;
}

int64_t TiledCloud::cached_points() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return cached_points_;
}

size_t TiledCloud::num_cached_tiles() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return cache_.size();
}

int64_t TiledCloud::num_tile_reads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return num_tile_reads_;
}

}  // namespace epiloc
