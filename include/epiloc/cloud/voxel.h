// Voxel-grid downsampling: one point per occupied voxel of a regular grid.
//
// The grid is axis-aligned with a corner at the origin of the cloud's frame: voxel
// (i, j, k) = floor(x / voxel_m), floor(y / voxel_m), floor(z / voxel_m), so clouds filtered
// separately share voxel boundaries. Each occupied voxel yields the centroid of its points'
// positions, the mean of their intensities and the mean (rounded) of their colours. The output
// is sorted by voxel index, lexicographically in (i, j, k), so its order does not depend on the
// input's order or on how the input was split into chunks. Sums are accumulated in double.
#pragma once

#include <cstdint>
#include <unordered_map>

#include "epiloc/cloud/point_cloud.h"

namespace epiloc {

// Accumulates points into voxels chunk by chunk, so a map can be merged from many scans while
// holding only one record per occupied voxel (about 100 bytes), never the raw points.
//   VoxelGrid grid(0.1);
//   for (...) grid.Add(scan);
//   PointCloud map = grid.Extract();
// Attributes: the output has intensity (colour) if any added cloud had it; a voxel none of whose
// points had it gets intensity 0 (grey 128), as PointCloud::Append fills.
class VoxelGrid {
 public:
  // Throws Error unless voxel_m is finite and positive.
  explicit VoxelGrid(double voxel_m);

  double voxel_m() const { return voxel_m_; }
  // Adds the points of `cloud`. Throws Error for an inconsistent cloud or a point whose voxel
  // index does not fit in 32 bits (|coordinate| / voxel_m >= 2^31).
  void Add(const PointCloud& cloud);
  // Occupied voxels so far.
  int64_t num_voxels() const { return static_cast<int64_t>(voxels_.size()); }
  // Points added so far.
  int64_t num_points_added() const { return num_points_added_; }
  // One point per occupied voxel, sorted by voxel index (see the top of this file).
  PointCloud Extract() const;
  // Forgets all points (keeps voxel_m).
  void Clear();

 private:
  struct Key {
    int32_t i, j, k;
    bool operator==(const Key& other) const { return i == other.i && j == other.j && k == other.k; }
  };
  struct KeyHash {
    size_t operator()(const Key& key) const;
  };
  struct Sums {
    double x = 0, y = 0, z = 0;
    double intensity = 0;
    uint64_t r = 0, g = 0, b = 0;
    uint32_t num_points = 0;
    uint32_t num_intensity = 0;
    uint32_t num_colour = 0;
  };

  double voxel_m_;
  std::unordered_map<Key, Sums, KeyHash> voxels_;
  int64_t num_points_added_ = 0;
  bool any_intensity_ = false;
  bool any_colour_ = false;
};

// One point per occupied voxel of side `voxel_m` (metres, > 0): centroid position, mean
// intensity, mean colour; deterministic (sorted by voxel index). Throws Error as VoxelGrid does.
PointCloud VoxelFilter(const PointCloud& cloud, double voxel_m);

}  // namespace epiloc
