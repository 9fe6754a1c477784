// Internals of the point-cloud renderer (render.h) shared by its sources.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <vector>

namespace epiloc {
namespace render_internal {

// A z-buffer entry: the depth's float bits above the point index. Positive floats order like
// their bit patterns, so the smallest key is the nearest point, and among equal depths the one
// with the lowest index: a total order, hence a result independent of the drawing order.
constexpr uint64_t kEmptyKey = ~uint64_t{0};

inline uint64_t PackKey(float depth_m, uint32_t index) {
  uint32_t bits;
  std::memcpy(&bits, &depth_m, sizeof(bits));
  return (static_cast<uint64_t>(bits) << 32) | index;
}
inline float KeyDepth(uint64_t key) {
  const uint32_t bits = static_cast<uint32_t>(key >> 32);
  float depth_m;
  std::memcpy(&depth_m, &bits, sizeof(depth_m));
  return depth_m;
}
inline uint32_t KeyIndex(uint64_t key) { return static_cast<uint32_t>(key); }

// Runs fn(begin, end, worker) on `num_workers` contiguous parts of [0, n) on as many threads
// (the calling thread takes part 0) and rethrows the first exception of a worker.
void ParallelFor(int num_workers,
                 int64_t n,
                 const std::function<void(int64_t begin, int64_t end, int worker)>& fn);

// Images of one rendering, row-major, width * height pixels.
struct RenderBuffers {
  int width = 0;
  int height = 0;
  int channels = 0;               // attribute channels per pixel: 0, 1 (intensity) or 3 (RGB)
  std::vector<float> depth;       // metres, 0 = empty
  std::vector<int32_t> index;     // point index, -1 = empty or filled
  std::vector<float> attributes;  // channels per pixel, unspecified where empty
};

// The hole-filling passes of render.h on `buffers` (rows split over `num_threads`); returns
// the number of pixels filled or replaced.
int64_t FillHoles(RenderBuffers* buffers,
                  int iterations,
                  int radius_px,
                  double see_through_ratio,
                  int num_threads);

}  // namespace render_internal
}  // namespace epiloc
