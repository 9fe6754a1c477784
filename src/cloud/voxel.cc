#include "epiloc/cloud/voxel.h"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr double kMaxIndex = 2147483647.0;

}  // namespace

size_t VoxelGrid::KeyHash::operator()(const Key& key) const {
  // Mixes the three indices with large odd multipliers (Teschner et al.'s spatial hash).
  const uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(key.i)) * 73856093ULL ^
                     static_cast<uint64_t>(static_cast<uint32_t>(key.j)) * 19349663ULL ^
                     static_cast<uint64_t>(static_cast<uint32_t>(key.k)) * 83492791ULL;
  return static_cast<size_t>(h ^ (h >> 29));
}

VoxelGrid::VoxelGrid(double voxel_m) : voxel_m_(voxel_m) {
  EPILOC_CHECK(std::isfinite(voxel_m) && voxel_m > 0, "VoxelGrid: voxel_m must be positive, got {}",
               voxel_m);
}

void VoxelGrid::Add(const PointCloud& cloud) {
  cloud.Check();
  const bool intensity = cloud.HasIntensity();
  const bool colour = cloud.HasColour();
  any_intensity_ = any_intensity_ || intensity;
  any_colour_ = any_colour_ || colour;
  const double inverse = 1.0 / voxel_m_;
  for (size_t n = 0; n < cloud.size(); ++n) {
    const Eigen::Vector3d p = cloud.positions[n].cast<double>();
    const Eigen::Vector3d index = (p * inverse).array().floor();
    if (!(index.cwiseAbs().maxCoeff() < kMaxIndex)) {
      Throw("VoxelGrid: point ({}, {}, {}) is outside the grid of {} m voxels (or not finite)",
            p.x(), p.y(), p.z(), voxel_m_);
    }
    Sums& sums = voxels_[Key{static_cast<int32_t>(index.x()), static_cast<int32_t>(index.y()),
                             static_cast<int32_t>(index.z())}];
    sums.x += p.x();
    sums.y += p.y();
    sums.z += p.z();
    ++sums.num_points;
    if (intensity) {
      sums.intensity += cloud.intensity[n];
      ++sums.num_intensity;
    }
    if (colour) {
      sums.r += cloud.rgb[n][0];
      sums.g += cloud.rgb[n][1];
      sums.b += cloud.rgb[n][2];
      ++sums.num_colour;
    }
  }
  num_points_added_ += static_cast<int64_t>(cloud.size());
}

PointCloud VoxelGrid::Extract() const {
  std::vector<std::pair<Key, const Sums*>> sorted;
  sorted.reserve(voxels_.size());
  for (const auto& [key, sums] : voxels_) sorted.emplace_back(key, &sums);
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) {
    return std::tie(a.first.i, a.first.j, a.first.k) < std::tie(b.first.i, b.first.j, b.first.k);
  });
  PointCloud out;
  out.Reserve(sorted.size(), any_intensity_, any_colour_);
  auto mean_channel = [](uint64_t sum, uint32_t n) {
    return static_cast<uint8_t>((sum + n / 2) / n);
  };
  for (const auto& [key, sums] : sorted) {
    const double n = sums->num_points;
    out.positions.emplace_back(static_cast<float>(sums->x / n), static_cast<float>(sums->y / n),
                               static_cast<float>(sums->z / n));
    if (any_intensity_) {
      out.intensity.push_back(sums->num_intensity == 0
                                  ? 0.0f
                                  : static_cast<float>(sums->intensity / sums->num_intensity));
    }
    if (any_colour_) {
      if (sums->num_colour == 0) {
        out.rgb.push_back({128, 128, 128});
      } else {
        out.rgb.push_back({mean_channel(sums->r, sums->num_colour),
                           mean_channel(sums->g, sums->num_colour),
                           mean_channel(sums->b, sums->num_colour)});
      }
    }
  }
  return out;
}

void VoxelGrid::Clear() {
  voxels_.clear();
  num_points_added_ = 0;
  any_intensity_ = false;
  any_colour_ = false;
}

PointCloud VoxelFilter(const PointCloud& cloud, double voxel_m) {
  VoxelGrid grid(voxel_m);
  grid.Add(cloud);
  return grid.Extract();
}

}  // namespace epiloc
