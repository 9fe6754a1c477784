// An in-memory point cloud: positions with optional per-point intensity and colour.
//
// Positions are float metres in the cloud's frame (epiloc's maps: the database's local ENU frame,
// x east, y north, z up); `intensity` is empty or one value per point in [0, 1]; `rgb` is empty
// or one colour per point (R, G, B order). Structure of arrays so a renderer can stream positions.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace epiloc {

struct PointCloud {
  std::vector<Eigen::Vector3f> positions;   // metres, in the cloud's frame
  std::vector<float> intensity;             // empty, or one per point in [0, 1]
  std::vector<std::array<uint8_t, 3>> rgb;  // empty, or one per point, R G B

  size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool HasIntensity() const { return !intensity.empty(); }
  bool HasColour() const { return !rgb.empty(); }
  // Reserves room for n points (and their intensity / colour where asked); adds no attribute.
  void Reserve(size_t n, bool with_intensity, bool with_colour);
  // Appends all points of `other`; attributes one side lacks are filled (intensity 0, grey
  // 128) only if this cloud has them. Throws Error if this cloud is non-empty, lacks an attribute
  // `other` has, and would thereby lose it (call Reserve/resize first).
  void Append(const PointCloud& other);
  // Throws Error if an attribute array has a size other than 0 or size().
  void Check() const;
};

// Axis-aligned bounds of the positions; min > max (empty box) for an empty cloud.
struct Bounds3f {
  Eigen::Vector3f min = Eigen::Vector3f::Constant(1e30f);
  Eigen::Vector3f max = Eigen::Vector3f::Constant(-1e30f);
  bool Empty() const { return (min.array() > max.array()).any(); }
  void Extend(const Eigen::Vector3f& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
};
Bounds3f ComputeBounds(const PointCloud& cloud);

}  // namespace epiloc
