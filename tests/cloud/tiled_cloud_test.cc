#include "epiloc/cloud/tiled_cloud.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <utility>

#include <gtest/gtest.h>

#include "cloud_test_util.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/voxel.h"
#include "test_util.h"

namespace epiloc {
namespace {

using TileKey = std::pair<int32_t, int32_t>;

// Input point indices per tile, in input order (the brute-force reference).
std::map<TileKey, std::vector<size_t>> TilesOf(const PointCloud& cloud, double tile_size_m) {
  std::map<TileKey, std::vector<size_t>> tiles;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const TileKey key{static_cast<int32_t>(std::floor(cloud.positions[i].x() / tile_size_m)),
                      static_cast<int32_t>(std::floor(cloud.positions[i].y() / tile_size_m))};
    tiles[key].push_back(i);
  }
  return tiles;
}

bool CellMeetsDisc(const TileKey& key, double s, const Eigen::Vector2d& c, double radius_m) {
  const double dx = std::max({key.first * s - c.x(), 0.0, c.x() - (key.first + 1) * s});
  const double dy = std::max({key.second * s - c.y(), 0.0, c.y() - (key.second + 1) * s});
  return dx * dx + dy * dy <= radius_m * radius_m;
}

PointCloud Expected(const PointCloud& cloud,
                    const std::map<TileKey, std::vector<size_t>>& tiles,
                    double s,
                    const Eigen::Vector2d& centre,
                    double radius_m) {
  PointCloud out;
  out.Reserve(0, true, true);
  for (const auto& [key, indices] : tiles) {
    if (!CellMeetsDisc(key, s, centre, radius_m)) continue;
    for (size_t i : indices) {
      out.positions.push_back(cloud.positions[i]);
      out.intensity.push_back(cloud.intensity[i]);
      out.rgb.push_back(cloud.rgb[i]);
    }
  }
  return out;
}

TEST(TiledCloud, BuildStreamsAndLoadMatchesBruteForce) {
  TempDir dir;
  const double s = 25.0;
  const PointCloud cloud = RandomCloud(1500000, 11, true, true, -150.0f, 250.0f);
  WritePointCloud(dir / "map.ply", cloud);
  TileOptions options;
  options.tile_size_m = s;
  options.chunk_points = 100000;
  options.max_buffered_points = 150000;  // forces many partial flushes
  int64_t last_progress = 0;
  const TileBuildSummary summary =
      BuildTiledCloud(dir / "map.ply", dir / "tiles", options, CloudReadOptions(),
                      [&](int64_t done, int64_t total) {
                        EXPECT_EQ(total, 1500000);
                        EXPECT_GT(done, last_progress);
                        last_progress = done;
                      });
  EXPECT_EQ(last_progress, 1500000);
  const auto tiles = TilesOf(cloud, s);
  EXPECT_EQ(summary.num_points_in, 1500000);
  EXPECT_EQ(summary.num_points_out, 1500000);
  EXPECT_EQ(summary.num_tiles, static_cast<int64_t>(tiles.size()));
  EXPECT_EQ(tiles.size(), 256u);
  EXPECT_EQ(summary.bounds.min, ComputeBounds(cloud).min);
  EXPECT_EQ(summary.bounds.max, ComputeBounds(cloud).max);
  for (const auto& entry : std::filesystem::directory_iterator(dir / "tiles")) {
    EXPECT_NE(entry.path().extension(), ".part");
  }

  TiledCloudOptions cloud_options;
  cloud_options.max_cached_points = 30000;  // about five tiles
  TiledCloud map(dir / "tiles", cloud_options);
  EXPECT_FALSE(map.single_file());
  EXPECT_EQ(map.tile_size_m(), s);
  EXPECT_EQ(map.num_points(), 1500000);
  EXPECT_TRUE(map.has_intensity() && map.has_colour());
  ASSERT_EQ(map.tiles().size(), tiles.size());
  for (const TileInfo& tile : map.tiles()) {
    EXPECT_EQ(tile.num_points, static_cast<int64_t>(tiles.at({tile.ix, tile.iy}).size()));
    EXPECT_GE(tile.bounds.min.x(), tile.cell_min_xy.x());
    EXPECT_LE(tile.bounds.max.y(), tile.cell_max_xy.y());
  }

  std::mt19937 rng(12);
  std::uniform_real_distribution<double> position(-200.0, 300.0);
  std::uniform_real_distribution<double> radius(0.0, 60.0);
  std::vector<std::pair<Eigen::Vector2d, double>> queries = {
      {{0.0, 0.0}, 0.0},        // a corner shared by four tiles
      {{12.5, 12.5}, 1.0},      // inside one tile
      {{-500.0, 0.0}, 10.0},    // off the map
      {{50.0, 50.0}, 1000.0}};  // everything
  for (int q = 0; q < 12; ++q) queries.push_back({{position(rng), position(rng)}, radius(rng)});
  for (const auto& [centre, radius_m] : queries) {
    SCOPED_TRACE("centre " + std::to_string(centre.x()) + " " + std::to_string(centre.y()) +
                 " radius " + std::to_string(radius_m));
    const PointCloud loaded = map.Load(Eigen::Vector3d(centre.x(), centre.y(), 7.0), radius_m);
    const PointCloud expected = Expected(cloud, tiles, s, centre, radius_m);
    if (expected.empty()) {
      EXPECT_TRUE(loaded.empty());
    } else {
      ExpectSameCloud(expected, loaded);
    }
    EXPECT_LE(map.cached_points(), cloud_options.max_cached_points);
  }
  EXPECT_EQ(map.Load(Eigen::Vector3d(0, 0, 0), 0.0).size(),
            tiles.at({-1, -1}).size() + tiles.at({-1, 0}).size() + tiles.at({0, -1}).size() +
                tiles.at({0, 0}).size());
  // A repeated small query is served from the cache.
  map.Load(Eigen::Vector3d(12.5, 12.5, 0), 1.0);
  const int64_t reads = map.num_tile_reads();
  map.Load(Eigen::Vector3d(12.5, 12.5, 0), 1.0);
  EXPECT_EQ(map.num_tile_reads(), reads);
  EXPECT_GE(map.num_cached_tiles(), 1u);
  ExpectError([&] { map.Load(Eigen::Vector3d(0, 0, 0), -1.0); }, {"radius"});

  // Without a cache every tile is read each time, and nothing is kept.
  cloud_options.max_cached_points = 0;
  TiledCloud uncached(dir / "tiles", cloud_options);
  uncached.Load(Eigen::Vector3d(12.5, 12.5, 0), 1.0);
  uncached.Load(Eigen::Vector3d(12.5, 12.5, 0), 1.0);
  EXPECT_EQ(uncached.num_tile_reads(), 2);
  EXPECT_EQ(uncached.cached_points(), 0);

  // An existing tile directory is kept unless asked to overwrite it.
  ExpectError([&] { BuildTiledCloud(dir / "map.ply", dir / "tiles", options); },
              {"tiles.json", "exists already"});
}

TEST(TiledCloud, ChunkSourceWithVoxelFilterAndOverwrite) {
  TempDir dir;
  const PointCloud cloud = RandomCloud(60000, 13, true, true, -40.0f, 40.0f);
  auto source_of = [&cloud](size_t chunk_points) {
    return [&cloud, chunk_points, begin = size_t{0}](PointCloud* chunk) mutable {
      if (begin >= cloud.size()) return false;
      const size_t end = std::min(cloud.size(), begin + chunk_points);
      chunk->positions.assign(cloud.positions.begin() + begin, cloud.positions.begin() + end);
      chunk->intensity.assign(cloud.intensity.begin() + begin, cloud.intensity.begin() + end);
      chunk->rgb.assign(cloud.rgb.begin() + begin, cloud.rgb.begin() + end);
      begin = end;
      return true;
    };
  };
  TileOptions options;
  options.tile_size_m = 10.0;
  options.voxel_m = 0.5;  // divides the tile size: no voxel straddles two tiles
  options.max_buffered_points = 5000;
  BuildTiledCloud(source_of(7000), dir / "t", options);
  options.voxel_m = 2.5;
  ExpectError([&] { BuildTiledCloud(source_of(7000), dir / "t", options); }, {"exists already"});
  options.overwrite = true;
  options.voxel_m = 0.5;
  const TileBuildSummary summary = BuildTiledCloud(source_of(7000), dir / "t", options);
  const PointCloud filtered = VoxelFilter(cloud, 0.5);
  EXPECT_EQ(summary.num_points_in, 60000);
  EXPECT_EQ(summary.num_points_out, static_cast<int64_t>(filtered.size()));
  EXPECT_EQ(summary.num_tiles, 64);
  TiledCloud map(dir / "t");
  PointCloud all = map.Load(Eigen::Vector3d::Zero(), 100.0);
  ASSERT_EQ(all.size(), filtered.size());
  // The same voxels, ordered by tile first: compare as sorted sets.
  auto sorted = [](const PointCloud& c) {
    std::vector<std::tuple<float, float, float, float, std::array<uint8_t, 3>>> v;
    for (size_t i = 0; i < c.size(); ++i) {
      v.emplace_back(c.positions[i].x(), c.positions[i].y(), c.positions[i].z(), c.intensity[i],
                     c.rgb[i]);
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(sorted(all), sorted(filtered));

  // Chunks must keep the attributes of the first.
  PointCloud odd = RandomCloud(10, 14, false, false);
  int calls = 0;
  ExpectError(
      [&] {
        BuildTiledCloud(
            [&](PointCloud* chunk) {
              *chunk = calls++ == 0 ? cloud : odd;
              return calls <= 2;
            },
            dir / "t", options);
      },
      {"attributes"});
}

TEST(TiledCloud, PlainFileIsOneTile) {
  TempDir dir;
  const PointCloud cloud = RandomCloud(5000, 15, true, false, 10.0f, 30.0f);
  WritePointCloud(dir / "small.pcd", cloud);
  TiledCloud map(dir / "small.pcd");
  EXPECT_TRUE(map.single_file());
  ASSERT_EQ(map.tiles().size(), 1u);
  EXPECT_EQ(map.num_points(), 5000);
  EXPECT_EQ(map.num_tile_reads(), 1);
  ExpectSameCloud(cloud, map.Load(Eigen::Vector3d(0, 0, 0), 15.0));  // reaches the corner
  EXPECT_TRUE(map.Load(Eigen::Vector3d(0, 0, 0), 14.0).empty());
  EXPECT_TRUE(map.Load(Eigen::Vector3d(100, 20, 0), 50.0).empty());
  EXPECT_EQ(map.num_tile_reads(), 1);  // served from the cache
}

TEST(TiledCloud, Errors) {
  TempDir dir;
  ExpectError([&] { TiledCloud map(dir / "missing"); }, {"missing", "does not exist"});
  ExpectError([&] { TiledCloud map(dir.str()); }, {"tiles.json", "cannot open"});
  WriteText(dir / "tiles.json", "{\"format\": \"epiloc-tiled-cloud\", \"version\": 1}");
  ExpectError([&] { TiledCloud map(dir.str()); }, {"tiles.json", "malformed"});
  WriteText(dir / "tiles.json", "{\"format\": \"something\"}");
  ExpectError([&] { TiledCloud map(dir.str()); }, {"tiles.json", "not an epiloc"});
  WriteText(dir / "tiles.json", "[1, 2");
  ExpectError([&] { TiledCloud map(dir.str()); }, {"tiles.json", "malformed"});

  // A tile whose file does not match the index.
  TileOptions options;
  WriteText(dir / "none.xyz", "");
  EXPECT_EQ(BuildTiledCloud(dir / "none.xyz", dir / "empty", options).num_tiles, 0);
  EXPECT_TRUE(TiledCloud(dir / "empty").Load(Eigen::Vector3d::Zero(), 1e6).empty());
  WriteText(dir / "one.xyz", "1 2 3\n4 5 6\n");
  BuildTiledCloud(dir / "one.xyz", dir / "one", options);
  WritePointCloud(dir / "one/tile_0_0.ply", RandomCloud(1, 16, false, false, 1.0f, 2.0f));
  TiledCloud map(dir / "one");
  ExpectError([&] { map.Load(Eigen::Vector3d(1, 1, 0), 1.0); },
              {"tile_0_0.ply", "has 1 points", "index says 2"});
  options.tile_size_m = -1;
  ExpectError([&] { BuildTiledCloud(dir / "one.xyz", dir / "other", options); }, {"tile_size_m"});
}

}  // namespace
}  // namespace epiloc
