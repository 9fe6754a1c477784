// Helpers shared by the cloud module's tests: random clouds, exact comparison, raw bytes.
#pragma once

#include <algorithm>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/cloud/point_cloud.h"

namespace epiloc {

// `n` points uniform in [min_xy, max_xy]^2 x [-5, 5] m with optional intensity and colour.
inline PointCloud RandomCloud(size_t n,
                              uint64_t seed,
                              bool intensity,
                              bool colour,
                              float min_xy = -100.0f,
                              float max_xy = 100.0f) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> xy(min_xy, max_xy);
  std::uniform_real_distribution<float> z(-5.0f, 5.0f);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::uniform_int_distribution<int> byte(0, 255);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(xy(rng), xy(rng), z(rng));
    if (intensity) cloud.intensity.push_back(unit(rng));
    if (colour) {
      cloud.rgb.push_back({static_cast<uint8_t>(byte(rng)), static_cast<uint8_t>(byte(rng)),
                           static_cast<uint8_t>(byte(rng))});
    }
  }
  return cloud;
}

// Bit-exact equality of positions and attributes (stops at the first difference).
inline void ExpectSameCloud(const PointCloud& expected, const PointCloud& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  ASSERT_EQ(expected.HasIntensity(), actual.HasIntensity());
  ASSERT_EQ(expected.HasColour(), actual.HasColour());
  for (size_t i = 0; i < expected.size(); ++i) {
    ASSERT_EQ(expected.positions[i], actual.positions[i]) << "point " << i;
    if (expected.HasIntensity()) {
      ASSERT_EQ(expected.intensity[i], actual.intensity[i]) << "point " << i;
    }
    if (expected.HasColour()) {
      ASSERT_EQ(expected.rgb[i], actual.rgb[i]) << "point " << i;
    }
  }
}

// Appends the bytes of `value`, reversed when `big_endian` (tests run on little-endian hosts).
template <typename T>
void PutBytes(T value, bool big_endian, std::string* out) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (big_endian) std::reverse(bytes, bytes + sizeof(T));
  out->append(bytes, sizeof(T));
}

inline void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

}  // namespace epiloc
