#include "epiloc/cloud/voxel.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include <gtest/gtest.h>

#include "cloud_test_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

TEST(Voxel, ExactCentroidsMeansAndOrder) {
  PointCloud cloud;
  auto add = [&](float x, float y, float z, float intensity, std::array<uint8_t, 3> rgb) {
    cloud.positions.emplace_back(x, y, z);
    cloud.intensity.push_back(intensity);
    cloud.rgb.push_back(rgb);
  };
  // Voxel (0, 0, 0) of 0.5 m: two points.
  add(0.125f, 0.25f, 0.0f, 0.25f, {10, 0, 255});
  add(0.375f, 0.25f, 0.5f - 0.0625f, 0.75f, {21, 1, 254});
  // Voxel (-1, 0, 0): three points, given after a point of another voxel.
  add(-0.125f, 0.0f, 0.0f, 1.0f, {0, 0, 0});
  add(2.0f, 2.0f, 2.0f, 0.5f, {7, 7, 7});  // voxel (4, 4, 4), alone
  add(-0.5f, 0.25f, 0.0f, 0.0f, {3, 3, 3});
  add(-0.375f, 0.125f, 0.25f, 0.5f, {3, 3, 6});

  const PointCloud filtered = VoxelFilter(cloud, 0.5);
  ASSERT_EQ(filtered.size(), 3u);
  // Sorted by voxel index: (-1, 0, 0), (0, 0, 0), (4, 4, 4).
  EXPECT_EQ(filtered.positions[0], Eigen::Vector3f(-1.0f / 3.0f, 0.125f, 0.25f / 3.0f));
  EXPECT_EQ(filtered.positions[1], Eigen::Vector3f(0.25f, 0.25f, 0.21875f));
  EXPECT_EQ(filtered.positions[2], Eigen::Vector3f(2.0f, 2.0f, 2.0f));
  EXPECT_FLOAT_EQ(filtered.intensity[0], 0.5f);
  EXPECT_FLOAT_EQ(filtered.intensity[1], 0.5f);
  EXPECT_EQ(filtered.rgb[0], (std::array<uint8_t, 3>{2, 2, 3}));     // 6/3, 6/3, 9/3
  EXPECT_EQ(filtered.rgb[1], (std::array<uint8_t, 3>{16, 1, 255}));  // 15.5 -> 16, 254.5 -> 255
  // Without attributes the output has none.
  PointCloud bare;
  bare.positions = cloud.positions;
  const PointCloud bare_filtered = VoxelFilter(bare, 0.5);
  EXPECT_EQ(bare_filtered.positions, filtered.positions);
  EXPECT_FALSE(bare_filtered.HasIntensity() || bare_filtered.HasColour());
}

TEST(Voxel, OnePointPerOccupiedVoxelInsideIt) {
  const double voxel_m = 0.7;
  const PointCloud cloud = RandomCloud(50000, 3, true, false, -20.0f, 20.0f);
  std::map<std::tuple<int, int, int>, int> occupied;
  for (const Eigen::Vector3f& p : cloud.positions) {
    ++occupied[{static_cast<int>(std::floor(p.x() / voxel_m)),
                static_cast<int>(std::floor(p.y() / voxel_m)),
                static_cast<int>(std::floor(p.z() / voxel_m))}];
  }
  const PointCloud filtered = VoxelFilter(cloud, voxel_m);
  ASSERT_EQ(filtered.size(), occupied.size());
  auto it = occupied.begin();
  for (size_t i = 0; i < filtered.size(); ++i, ++it) {
    const auto& [ix, iy, iz] = it->first;
    const Eigen::Vector3d p = filtered.positions[i].cast<double>();
    EXPECT_GE(p.x(), ix * voxel_m - 1e-5);
    EXPECT_LE(p.x(), (ix + 1) * voxel_m + 1e-5);
    EXPECT_GE(p.y(), iy * voxel_m - 1e-5);
    EXPECT_LE(p.z(), (iz + 1) * voxel_m + 1e-5);
    ASSERT_GE(filtered.intensity[i], 0.0f);
    ASSERT_LE(filtered.intensity[i], 1.0f);
  }
}

TEST(Voxel, IncrementalEqualsOneShot) {
  std::mt19937 rng(4);
  const PointCloud cloud = RandomCloud(200000, 5, true, true, -30.0f, 30.0f);
  const PointCloud one_shot = VoxelFilter(cloud, 0.25);
  VoxelGrid grid(0.25);
  size_t begin = 0;
  std::uniform_int_distribution<size_t> chunk_size(1, 20000);
  int num_chunks = 0;
  while (begin < cloud.size()) {
    const size_t end = std::min(cloud.size(), begin + chunk_size(rng));
    PointCloud chunk;
    chunk.positions.assign(cloud.positions.begin() + begin, cloud.positions.begin() + end);
    chunk.intensity.assign(cloud.intensity.begin() + begin, cloud.intensity.begin() + end);
    chunk.rgb.assign(cloud.rgb.begin() + begin, cloud.rgb.begin() + end);
    grid.Add(chunk);
    begin = end;
    ++num_chunks;
  }
  EXPECT_GT(num_chunks, 5);
  EXPECT_EQ(grid.num_points_added(), 200000);
  EXPECT_EQ(grid.num_voxels(), static_cast<int64_t>(one_shot.size()));
  ExpectSameCloud(one_shot, grid.Extract());
  // The input's order does not change the voxels (sums differ in rounding only).
  PointCloud shuffled = cloud;
  std::vector<size_t> order(cloud.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  for (size_t i = 0; i < order.size(); ++i) {
    shuffled.positions[i] = cloud.positions[order[i]];
    shuffled.intensity[i] = cloud.intensity[order[i]];
    shuffled.rgb[i] = cloud.rgb[order[i]];
  }
  const PointCloud from_shuffled = VoxelFilter(shuffled, 0.25);
  ASSERT_EQ(from_shuffled.size(), one_shot.size());
  for (size_t i = 0; i < one_shot.size(); ++i) {
    ASSERT_LT((from_shuffled.positions[i] - one_shot.positions[i]).norm(), 1e-5f);
    ASSERT_EQ(from_shuffled.rgb[i], one_shot.rgb[i]);
  }
  grid.Clear();
  EXPECT_EQ(grid.num_voxels(), 0);
  EXPECT_TRUE(grid.Extract().empty());
}

TEST(Voxel, MixedAttributesAndErrors) {
  VoxelGrid grid(1.0);
  PointCloud a = RandomCloud(1, 6, true, false, 0.1f, 0.9f);
  a.positions[0].z() = 0.5f;
  PointCloud b = RandomCloud(1, 7, false, true, 5.1f, 5.9f);
  b.positions[0].z() = 0.5f;
  grid.Add(a);
  grid.Add(b);
  const PointCloud out = grid.Extract();
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out.intensity[1], 0.0f);  // the voxel of b had no intensity
  EXPECT_EQ(out.rgb[0], (std::array<uint8_t, 3>{128, 128, 128}));
  EXPECT_EQ(out.rgb[1], b.rgb[0]);
  ExpectError([] { VoxelGrid(0.0); }, {"voxel_m"});
  ExpectError([] { VoxelGrid(std::nan("")); }, {"voxel_m"});
  PointCloud far;
  far.positions.emplace_back(1e9f, 0.0f, 0.0f);
  ExpectError([&] { VoxelFilter(far, 0.1); }, {"outside the grid"});
}

}  // namespace
}  // namespace epiloc
