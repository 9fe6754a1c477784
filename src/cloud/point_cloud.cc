#include "epiloc/cloud/point_cloud.h"

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr std::array<uint8_t, 3> kFillColour = {128, 128, 128};

}  // namespace

void PointCloud::Reserve(size_t n, bool with_intensity, bool with_colour) {
  positions.reserve(n);
  if (with_intensity) intensity.reserve(n);
  if (with_colour) rgb.reserve(n);
}

void PointCloud::Append(const PointCloud& other) {
  other.Check();
  Check();
  const size_t old_size = size();
  // An empty cloud takes the attributes of the first cloud appended to it.
  const bool adopt = old_size == 0;
  if (!adopt && !HasIntensity() && other.HasIntensity()) {
    Throw("PointCloud::Append: this cloud has no intensity and would lose that of the other");
  }
  if (!adopt && !HasColour() && other.HasColour()) {
    Throw("PointCloud::Append: this cloud has no colour and would lose that of the other");
  }
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  if (other.HasIntensity()) {
    intensity.insert(intensity.end(), other.intensity.begin(), other.intensity.end());
  } else if (HasIntensity()) {
    intensity.resize(size(), 0.0f);
  }
  if (other.HasColour()) {
    rgb.insert(rgb.end(), other.rgb.begin(), other.rgb.end());
  } else if (HasColour()) {
    rgb.resize(size(), kFillColour);
  }
}

void PointCloud::Check() const {
  EPILOC_CHECK(intensity.empty() || intensity.size() == positions.size(),
               "PointCloud: {} intensities for {} points", intensity.size(), positions.size());
  EPILOC_CHECK(rgb.empty() || rgb.size() == positions.size(),
               "PointCloud: {} colours for {} points", rgb.size(), positions.size());
}

Bounds3f ComputeBounds(const PointCloud& cloud) {
  Bounds3f bounds;
  for (const Eigen::Vector3f& p : cloud.positions) bounds.Extend(p);
  return bounds;
}

}  // namespace epiloc
