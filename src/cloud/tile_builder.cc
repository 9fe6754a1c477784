// BuildTiledCloud: streams points through bounded per-tile write buffers into the tiles' PLY
// files (appended behind a placeholder header of fixed length), then writes each real header in
// place and the index.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <tuple>
#include <unordered_map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "cloud_io_internal.h"
#include "epiloc/cloud/tiled_cloud.h"
#include "epiloc/cloud/voxel.h"
#include "epiloc/core/error.h"

namespace epiloc {

namespace cloud_internal {

std::string TileFileName(int32_t ix, int32_t iy) { return fmt::format("tile_{}_{}.ply", ix, iy); }

int32_t TileIndex(double coordinate, double tile_size_m) {
  const double index = std::floor(coordinate / tile_size_m);
  if (!(std::abs(index) < 2147483647.0)) {
    Throw("coordinate {} m is outside the grid of {} m tiles", coordinate, tile_size_m);
  }
  return static_cast<int32_t>(index);
}

}  // namespace cloud_internal

namespace {

namespace fs = std::filesystem;
using cloud_internal::TileFileName;
using cloud_internal::TileIndex;

struct TileKey {
  int32_t ix, iy;
  bool operator==(const TileKey& other) const { return ix == other.ix && iy == other.iy; }
  bool operator<(const TileKey& other) const {
    return std::tie(ix, iy) < std::tie(other.ix, other.iy);
  }
};

struct TileKeyHash {
  size_t operator()(const TileKey& key) const {
    return std::hash<uint64_t>()((static_cast<uint64_t>(static_cast<uint32_t>(key.ix)) << 32) |
                                 static_cast<uint32_t>(key.iy));
  }
};

struct Bucket {
  std::string buffer;  // binary PLY records not yet appended to the tile file
  int64_t num_points = 0;
  Bounds3f bounds;
  size_t pending = 0;         // points of the current chunk (TileWriter::Add)
  char* cursor = nullptr;     // where the next record of the current chunk goes
  bool file_started = false;  // the tile file exists, with a placeholder header
};

// Tile files start with a header of this many bytes, rewritten with the count at the end.
size_t ReservedHeaderBytes(bool with_intensity, bool with_colour) {
  return cloud_internal::PlyHeader(int64_t{999999999999999}, with_intensity, with_colour, true)
      .size();
}

bool IsTileFile(const fs::path& path) {
  return path.filename().string().rfind("tile_", 0) == 0 && path.extension() == ".ply";
}

nlohmann::json VectorJson(const Eigen::Vector3f& v) { return {v.x(), v.y(), v.z()}; }

class TileWriter {
 public:
  TileWriter(const std::string& out_dir, const TileOptions& options)
      : out_dir_(out_dir), options_(options) {
    options.Check();
    std::error_code error;
    fs::create_directories(out_dir_, error);
    EPILOC_CHECK(fs::is_directory(out_dir_), "{}: cannot create the tile directory ({})", out_dir,
                 error.message());
    const fs::path index = out_dir_ / cloud_internal::kTileIndexName;
    if (fs::exists(index) && !options.overwrite) {
      Throw("{}: a tiled cloud exists already (set overwrite to replace it)", index.string());
    }
    // Tiles of an earlier (or interrupted) build would mix with this one's.
    fs::remove(index);
    for (const auto& entry : fs::directory_iterator(out_dir_)) {
      if (entry.is_regular_file() && IsTileFile(entry.path())) fs::remove(entry.path());
    }
  }

  void Add(const PointCloud& chunk) {
    chunk.Check();
    if (chunk.empty()) return;
    if (!attributes_known_) {
      attributes_known_ = true;
      with_intensity_ = chunk.HasIntensity();
      with_colour_ = chunk.HasColour();
      record_bytes_ = cloud_internal::PlyRecordBytes(with_intensity_, with_colour_);
    }
    EPILOC_CHECK(chunk.HasIntensity() == with_intensity_ && chunk.HasColour() == with_colour_,
                 "{}: a chunk's attributes (intensity {}, colour {}) differ from the first's",
                 out_dir_.string(), chunk.HasIntensity(), chunk.HasColour());
    // Bucket every point, grow each touched buffer once, then encode the records in place.
    bucket_of_.resize(chunk.size());
    std::vector<Bucket*> touched;
    Bucket* last = nullptr;
    TileKey last_key{0, 0};
    for (size_t i = 0; i < chunk.size(); ++i) {
      const Eigen::Vector3f& p = chunk.positions[i];
      const TileKey key{TileIndex(p.x(), options_.tile_size_m),
                        TileIndex(p.y(), options_.tile_size_m)};
      if (last == nullptr || !(key == last_key)) {
        last = &buckets_[key];  // node-based map: pointers stay valid
        last_key = key;
      }
      if (last->pending++ == 0) touched.push_back(last);
      ++last->num_points;
      last->bounds.Extend(p);
      bucket_of_[i] = last;
    }
    for (Bucket* bucket : touched) {
      const size_t old_size = bucket->buffer.size();
      bucket->buffer.resize(old_size + bucket->pending * record_bytes_);
      bucket->cursor = bucket->buffer.data() + old_size;
      bucket->pending = 0;
    }
    for (size_t i = 0; i < chunk.size(); ++i) {
      bucket_of_[i]->cursor = cloud_internal::EncodePlyRecord(chunk, i, bucket_of_[i]->cursor);
    }
    num_points_in_ += static_cast<int64_t>(chunk.size());
    buffered_points_ += static_cast<int64_t>(chunk.size());
    if (buffered_points_ > options_.max_buffered_points) Flush(options_.max_buffered_points / 2);
  }

  TileBuildSummary Finish() {
    Flush(0);
    std::vector<TileKey> keys;
    keys.reserve(buckets_.size());
    for (const auto& [key, bucket] : buckets_) keys.push_back(key);
    std::sort(keys.begin(), keys.end());
    TileBuildSummary summary;
    summary.num_points_in = num_points_in_;
    nlohmann::json tiles = nlohmann::json::array();
    for (const TileKey& key : keys) {
      Bucket& bucket = buckets_.at(key);
      const fs::path tile_path = TilePath(key);
      FinishTile(bucket, tile_path);
      summary.num_points_out += bucket.num_points;
      summary.bounds.Extend(bucket.bounds.min);
      summary.bounds.Extend(bucket.bounds.max);
      tiles.push_back({{"ix", key.ix},
                       {"iy", key.iy},
                       {"file", tile_path.filename().string()},
                       {"num_points", bucket.num_points},
                       {"min", VectorJson(bucket.bounds.min)},
                       {"max", VectorJson(bucket.bounds.max)}});
    }
    summary.num_tiles = static_cast<int64_t>(keys.size());
    nlohmann::json index = {
        {"format", "epiloc-tiled-cloud"},
        {"version", 1},
        {"tile_size_m", options_.tile_size_m},
        {"has_intensity", with_intensity_},
        {"has_colour", with_colour_},
        {"num_points", summary.num_points_out},
        {"bounds",
         {{"min", VectorJson(summary.bounds.min)}, {"max", VectorJson(summary.bounds.max)}}},
        {"tiles", tiles}};
    const fs::path index_path = out_dir_ / cloud_internal::kTileIndexName;
    const std::string temporary = index_path.string() + ".tmp";
    std::ofstream out;
    cloud_internal::OpenForWriting(temporary, &out);
    out << index.dump(1) << "\n";
    cloud_internal::CloseOrThrow(temporary, &out);
    fs::rename(temporary, index_path);
    return summary;
  }

 private:
  fs::path TilePath(const TileKey& key) const { return out_dir_ / TileFileName(key.ix, key.iy); }

  // Appends the largest buffers to their tile files until at most `keep_points` stay buffered.
  void Flush(int64_t keep_points) {
    if (buffered_points_ <= keep_points) return;
    std::vector<std::pair<size_t, Bucket*>> by_size;
    std::vector<TileKey> keys;
    for (auto& [key, bucket] : buckets_) {
      if (!bucket.buffer.empty()) {
        by_size.emplace_back(bucket.buffer.size(), &bucket);
        keys.push_back(key);
      }
    }
    std::vector<size_t> order(by_size.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
      return by_size[a].first > by_size[b].first ||
             (by_size[a].first == by_size[b].first && keys[a] < keys[b]);
    });
    for (size_t k : order) {
      if (buffered_points_ <= keep_points) break;
      Bucket& bucket = *by_size[k].second;
      const std::string path = TilePath(keys[k]).string();
      std::ofstream out(path,
                        std::ios::binary | (bucket.file_started ? std::ios::app : std::ios::trunc));
      EPILOC_CHECK(out.good(), "{}: cannot open for writing", path);
      if (!bucket.file_started) {
        out << std::string(ReservedHeaderBytes(with_intensity_, with_colour_), ' ');
        bucket.file_started = true;
      }
      out.write(bucket.buffer.data(), static_cast<std::streamsize>(bucket.buffer.size()));
      cloud_internal::CloseOrThrow(path, &out);
      buffered_points_ -= static_cast<int64_t>(bucket.buffer.size() / record_bytes_);
      std::string().swap(bucket.buffer);  // give the memory back, not just the size
    }
  }

  // Writes the real header over the placeholder; voxel-filters the tile if asked.
  void FinishTile(Bucket& bucket, const fs::path& tile_path) {
    const std::string path = tile_path.string();
    const size_t header_bytes = ReservedHeaderBytes(with_intensity_, with_colour_);
    const auto expected = header_bytes + static_cast<uintmax_t>(bucket.num_points) * record_bytes_;
    EPILOC_CHECK(fs::file_size(path) == expected, "{}: has {} bytes, {} expected", path,
                 fs::file_size(path), expected);
    {
      std::ofstream out(path, std::ios::binary | std::ios::in | std::ios::out);
      EPILOC_CHECK(out.good(), "{}: cannot open for writing", path);
      out << cloud_internal::PlyHeader(bucket.num_points, with_intensity_, with_colour_, true,
                                       header_bytes);
      cloud_internal::CloseOrThrow(path, &out);
    }
    if (options_.voxel_m > 0) {
      VoxelGrid grid(options_.voxel_m);
      ForEachPointChunk(tile_path.string(), options_.chunk_points,
                        [&](const PointCloud& chunk) { grid.Add(chunk); });
      const PointCloud filtered = grid.Extract();
      WritePointCloud(tile_path.string(), filtered);
      bucket.num_points = static_cast<int64_t>(filtered.size());
      bucket.bounds = ComputeBounds(filtered);
    }
  }

  fs::path out_dir_;
  TileOptions options_;
  bool attributes_known_ = false;
  bool with_intensity_ = false;
  bool with_colour_ = false;
  size_t record_bytes_ = 0;
  std::unordered_map<TileKey, Bucket, TileKeyHash> buckets_;
  std::vector<Bucket*> bucket_of_;  // per point of the current chunk
  int64_t num_points_in_ = 0;
  int64_t buffered_points_ = 0;
};

}  // namespace

void TileOptions::Check() const {
  EPILOC_CHECK(std::isfinite(tile_size_m) && tile_size_m > 0,
               "TileOptions: tile_size_m must be positive, got {}", tile_size_m);
  EPILOC_CHECK(chunk_points > 0, "TileOptions: chunk_points must be positive, got {}",
               chunk_points);
  EPILOC_CHECK(max_buffered_points > 0, "TileOptions: max_buffered_points must be positive, got {}",
               max_buffered_points);
  EPILOC_CHECK(std::isfinite(voxel_m) && voxel_m >= 0,
               "TileOptions: voxel_m must be 0 (off) or positive, got {}", voxel_m);
}

TileBuildSummary BuildTiledCloud(const PointChunkSource& source,
                                 const std::string& out_dir,
                                 const TileOptions& options,
                                 const ProgressCallback& progress) {
  TileWriter writer(out_dir, options);
  PointCloud chunk;
  int64_t done = 0;
  while (source(&chunk)) {
    writer.Add(chunk);
    done += static_cast<int64_t>(chunk.size());
    if (progress) progress(done, 0);
  }
  return writer.Finish();
}

TileBuildSummary BuildTiledCloud(const std::string& input_path,
                                 const std::string& out_dir,
                                 const TileOptions& options,
                                 const CloudReadOptions& read_options,
                                 const ProgressCallback& progress) {
  options.Check();
  PointCloudReader reader(input_path, read_options);
  const int64_t total = std::max<int64_t>(reader.info().num_points, 0);
  TileWriter writer(out_dir, options);
  PointCloud chunk;
  while (reader.ReadChunk(options.chunk_points, &chunk)) {
    writer.Add(chunk);
    if (progress) progress(reader.stats().num_records, total);
  }
  TileBuildSummary summary = writer.Finish();
  summary.num_non_finite = reader.stats().num_non_finite;
  return summary;
}

}  // namespace epiloc
