// Bounded-memory access to large point-cloud maps (tens of millions of points): the map is cut
// into square tiles in x and y once (BuildTiledCloud, streaming), and a TiledCloud loads only the
// tiles near a pose, keeping recently used tiles in an LRU cache of bounded size.
//
// Tile directory format (version 1):
//   tiles.json            the index, written last (a directory without it is incomplete)
//   tile_<ix>_<iy>.ply    one binary little-endian PLY per non-empty tile: x y z (float32,
//                         metres), then intensity (float32, [0, 1]) and red green blue (uint8)
//                         where the map has them. Any PLY reader opens it. (Its header has a
//                         fixed length, padded with spaces in its comment line, because it is
//                         written last over a placeholder.)
// Tile (ix, iy) is the cell x in [ix * s, (ix + 1) * s), y in [iy * s, (iy + 1) * s) of the
// cloud's frame (s = tile_size_m; z unbounded). The index:
//   {"format": "epiloc-tiled-cloud", "version": 1, "tile_size_m": 25.0,
//    "has_intensity": true, "has_colour": false, "num_points": 1234567,
//    "bounds": {"min": [x, y, z], "max": [x, y, z]},
//    "tiles": [{"ix": 0, "iy": -1, "file": "tile_0_-1.ply", "num_points": 4567,
//               "min": [x, y, z], "max": [x, y, z]}, ...]}
// with tiles sorted by (ix, iy) and min / max the bounds of the tile's points, metres.
#pragma once

#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/point_cloud.h"
#include "epiloc/core/progress.h"

namespace epiloc {

struct TileOptions {
  double tile_size_m = 25.0;              // side of a square tile in x and y, metres
  int64_t chunk_points = 1000000;         // points read from the input at a time
  int64_t max_buffered_points = 4000000;  // points held in per-tile write buffers before the
                                          // largest are appended to their tile files
  double voxel_m = 0.0;                   // > 0: VoxelFilter each tile with this voxel side
                                          // (metres; voxels do not straddle tiles when
                                          // tile_size_m is a multiple of it)
  bool overwrite = false;                 // replace an existing tile directory's tiles
  // Throws Error naming the first invalid field.
  void Check() const;
};

struct TileBuildSummary {
  int64_t num_points_in = 0;   // points taken from the input (non-finite ones already dropped)
  int64_t num_points_out = 0;  // points in the tiles (fewer than num_points_in with voxel_m > 0)
  int64_t num_tiles = 0;
  int64_t num_non_finite = 0;  // input records dropped for a non-finite x, y or z (file input)
  Bounds3f bounds;             // of the points written
};

// Replaces *chunk by the next points of a stream; returns false (chunk contents ignored) when
// none are left. Every non-empty chunk must have the attributes of the first one.
using PointChunkSource = std::function<bool(PointCloud* chunk)>;

// Cuts the point-cloud file `input_path` (any format ReadPointCloud reads) into a tile directory
// `out_dir` (created if missing; tile_*.ply files already in it are removed), streaming: memory
// is bounded by chunk_points + max_buffered_points points (about 20 bytes each, buffers up to
// twice that; plus ~100 bytes per tile and, with voxel_m > 0, one tile's voxels), whatever the
// input's size: with the defaults about 200 MB for 10 or 20 million points. `progress`
// (optional) gets (points read, points declared or 0). Throws Error for an unreadable input, an
// existing tile directory without options.overwrite, or a write failure.
TileBuildSummary BuildTiledCloud(const std::string& input_path,
                                 const std::string& out_dir,
                                 const TileOptions& options = TileOptions(),
                                 const CloudReadOptions& read_options = CloudReadOptions(),
                                 const ProgressCallback& progress = nullptr);

// As above from a stream of chunks (e.g. many scans already in the map frame).
TileBuildSummary BuildTiledCloud(const PointChunkSource& source,
                                 const std::string& out_dir,
                                 const TileOptions& options = TileOptions(),
                                 const ProgressCallback& progress = nullptr);

struct TiledCloudOptions {
  int64_t max_cached_points = 20000000;  // points of loaded tiles kept in memory (LRU); 0: none
  CloudReadOptions read_options;         // for a plain cloud file opened as one tile
  // Throws Error naming the first invalid field.
  void Check() const;
};

struct TileInfo {
  int32_t ix = 0;    // tile index in x (0 for a single-file cloud)
  int32_t iy = 0;    // tile index in y
  std::string path;  // the tile's file
  int64_t num_points = 0;
  Bounds3f bounds;              // of the tile's points, metres
  Eigen::Vector2d cell_min_xy;  // the tile's cell in x y, metres (a single file: its bounds)
  Eigen::Vector2d cell_max_xy;
};

// A tiled map opened for loading around poses. Load() is thread-safe (one mutex; tile reads
// happen under it).
class TiledCloud {
 public:
  // Opens a tile directory (its tiles.json) or a plain point-cloud file, which becomes one tile
  // covering its points' bounds (read once here to get them). Throws Error for a missing or
  // malformed index or an unreadable file.
  explicit TiledCloud(const std::string& path,
                      const TiledCloudOptions& options = TiledCloudOptions());
  TiledCloud(const TiledCloud&) = delete;
  TiledCloud& operator=(const TiledCloud&) = delete;

  bool single_file() const { return single_file_; }
  double tile_size_m() const { return tile_size_m_; }  // 0 for a single file
  const std::vector<TileInfo>& tiles() const { return tiles_; }
  int64_t num_points() const { return num_points_; }
  const Bounds3f& bounds() const { return bounds_; }
  bool has_intensity() const { return has_intensity_; }
  bool has_colour() const { return has_colour_; }

  // Indices into tiles() of the tiles whose cell meets the disc of `radius_m` (metres, >= 0)
  // around centre's x y (z ignored), ascending.
  std::vector<size_t> TilesNear(const Eigen::Vector3d& centre, double radius_m) const;
  // All points of the tiles TilesNear() names (whole tiles, not cropped to the disc),
  // concatenated in tile order. Tiles come from the cache or are read and cached; afterwards
  // the least recently used are evicted until at most max_cached_points remain cached (a tile
  // larger than that is read every time). Throws Error if a tile file is unreadable or does not
  // match the index.
  PointCloud Load(const Eigen::Vector3d& centre, double radius_m);

  int64_t cached_points() const;
  size_t num_cached_tiles() const;
  int64_t num_tile_reads() const;  // tile files read so far (cache misses)

 private:
  std::shared_ptr<const PointCloud> GetTile(size_t index);

  TiledCloudOptions options_;
  bool single_file_ = false;
  double tile_size_m_ = 0.0;
  std::vector<TileInfo> tiles_;
  int64_t num_points_ = 0;
  Bounds3f bounds_;
  bool has_intensity_ = false;
  bool has_colour_ = false;

  mutable std::mutex mutex_;
  std::list<size_t> lru_;  // most recently used first
  struct CacheEntry {
    std::shared_ptr<const PointCloud> cloud;
    std::list<size_t>::iterator position;
  };
  std::unordered_map<size_t, CacheEntry> cache_;
  int64_t cached_points_ = 0;
  int64_t num_tile_reads_ = 0;
};

}  // namespace epiloc
