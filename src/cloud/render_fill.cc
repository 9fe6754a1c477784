// Hole filling and see-through removal of the point-cloud renderer (rule in render.h) and the
// renderer's thread helper.
#include <algorithm>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>
#include <utility>

#include "render_internal.h"

namespace epiloc {
namespace render_internal {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

struct Step {
  int dx;
  int dy;
};
// Directions 2k and 2k + 1 are the two sides of axis k.
constexpr int kNumDirections = 8;
constexpr Step kDirections[kNumDirections] = {{1, 0}, {-1, 0},  {0, 1},  {0, -1},
                                              {1, 1}, {-1, -1}, {1, -1}, {-1, 1}};
constexpr int kMinEnclosingAxes = 2;

// The input of a pass: depth with empty pixels at +infinity, so "nearer than the threshold" is
// one comparison that no empty pixel passes, framed by `radius` rows and columns of +infinity,
// so that no walk or window of `radius` steps needs a bounds check.
struct PaddedDepth {
  int width = 0;  // image width + 2 radius
  int radius = 0;
  std::vector<float> values;
  const float* At(int x, int y) const {
    return values.data() + static_cast<int64_t>(y + radius) * width + (x + radius);
  }
};

// Steps (1 to radius) to the first pixel nearer than `threshold_m` along `step`, 0 if none.
inline int Walk(const PaddedDepth& depth, int x, int y, Step step, float threshold_m) {
  const float* pixel = depth.At(x, y);
  const int64_t stride = static_cast<int64_t>(step.dy) * depth.width + step.dx;
  for (int s = 1; s <= depth.radius; ++s) {
    pixel += stride;
    if (*pixel < threshold_m) return s;
  }
  return 0;
}

// minima[d * width + x]: the nearest depth within `radius` steps from (x, y) along direction d
// (+infinity if none). Direction by direction over the whole row, up to four steps per sweep,
// so the loops vectorise and store little; this makes "is the pixel enclosed?" cheap for every
// pixel and leaves the walks to the few that are.
void DirectionalMinima(const PaddedDepth& depth, int width, int y, float* minima) {
  for (int d = 0; d < kNumDirections; ++d) {
    float* out = minima + static_cast<int64_t>(d) * width;
    const Step step = kDirections[d];
    for (int k0 = 1; k0 <= depth.radius; k0 += 4) {
      const float* p[4];
      for (int j = 0; j < 4; ++j) {
        const int k = std::min(k0 + j, depth.radius);  // repeats the last row: harmless
        p[j] = depth.At(step.dx * k, y + step.dy * k);
      }
      if (k0 == 1) {
        for (int x = 0; x < width; ++x) {
          out[x] = std::min(std::min(p[0][x], p[1][x]), std::min(p[2][x], p[3][x]));
        }
      } else {
        for (int x = 0; x < width; ++x) {
          out[x] =
              std::min(out[x], std::min(std::min(p[0][x], p[1][x]), std::min(p[2][x], p[3][x])));
        }
      }
    }
  }
}

// One pass over rows [row_begin, row_end): reads `depth` and `in_attributes`, writes those rows
// of `out_depth` (0 where empty) and `out_attributes`, and sets `index` to -1 where it fills.
// Returns the pixels not filled before that it fills.
int64_t FillRows(const PaddedDepth& depth,
                 const float* in_attributes,
                 int width,
                 int channels,
                 float threshold_factor,
                 int row_begin,
                 int row_end,
                 float* out_depth,
                 float* out_attributes,
                 int32_t* index) {
  std::vector<float> minima(static_cast<size_t>(kNumDirections) * width);
  std::vector<float> thresholds(width);
  std::vector<int32_t> num_enclosing(width);
  int64_t filled = 0;
  for (int y = row_begin; y < row_end; ++y) {
    const int64_t row_start = static_cast<int64_t>(y) * width;
    const float* row = depth.At(0, y);
    for (int x = 0; x < width; ++x) out_depth[row_start + x] = row[x] < kInfinity ? row[x] : 0.0f;
    std::copy(in_attributes + row_start * channels, in_attributes + (row_start + width) * channels,
              out_attributes + row_start * channels);
    DirectionalMinima(depth, width, y, minima.data());
    // Empty pixels: d and the threshold are infinite, any covered pixel is nearer.
    for (int x = 0; x < width; ++x) thresholds[x] = row[x] * threshold_factor;
    std::fill(num_enclosing.begin(), num_enclosing.end(), 0);
    for (int axis = 0; axis < 4; ++axis) {
      const float* side_a = minima.data() + static_cast<int64_t>(2 * axis) * width;
      const float* side_b = side_a + width;
      for (int x = 0; x < width; ++x) {
        num_enclosing[x] += (side_a[x] < thresholds[x]) & (side_b[x] < thresholds[x]);
      }
    }
    for (int x = 0; x < width; ++x) {
      if (num_enclosing[x] < kMinEnclosingAxes) continue;
      const float d = row[x];
      const float threshold = thresholds[x];
      // Inverse depth is linear along an image line on a plane; attributes are interpolated
      // linearly in the image. Short spans are more trustworthy, hence the weight 1 / span.
      double weight_sum = 0.0;
      double inverse_depth = 0.0;
      double attribute[3] = {0.0, 0.0, 0.0};
      for (int axis = 0; axis < 4; ++axis) {
        const Step step_a = kDirections[2 * axis];
        const Step step_b = kDirections[2 * axis + 1];
        const int a = Walk(depth, x, y, step_a, threshold);
        const int b = Walk(depth, x, y, step_b, threshold);
        if (a == 0 || b == 0) continue;
        const int ax = x + a * step_a.dx, ay = y + a * step_a.dy;
        const int bx = x + b * step_b.dx, by = y + b * step_b.dy;
        const double t = static_cast<double>(a) / (a + b);  // 0 at a, 1 at b
        const double weight = (axis >= 2 ? 0.70710678 : 1.0) / (a + b);
        weight_sum += weight;
        inverse_depth += weight * ((1.0 - t) / *depth.At(ax, ay) + t / *depth.At(bx, by));
        const float* attributes_a =
            in_attributes + (static_cast<int64_t>(ay) * width + ax) * channels;
        const float* attributes_b =
            in_attributes + (static_cast<int64_t>(by) * width + bx) * channels;
        for (int c = 0; c < channels; ++c) {
          attribute[c] += weight * ((1.0 - t) * attributes_a[c] + t * attributes_b[c]);
        }
      }
      const int64_t pixel = row_start + x;
      out_depth[pixel] = static_cast<float>(weight_sum / inverse_depth);
      for (int c = 0; c < channels; ++c) {
        out_attributes[pixel * channels + c] = static_cast<float>(attribute[c] / weight_sum);
      }
      filled += !(d < kInfinity && index[pixel] < 0);
      index[pixel] = -1;
    }
  }
  return filled;
}

}  // namespace

void ParallelFor(int num_workers,
                 int64_t n,
                 const std::function<void(int64_t begin, int64_t end, int worker)>& fn) {
  num_workers = static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(num_workers, n)));
  if (num_workers == 1) {
    fn(0, n, 0);
    return;
  }
  std::exception_ptr error;
  std::mutex mutex;
  auto run = [&](int worker) {
    try {
      fn(n * worker / num_workers, n * (worker + 1) / num_workers, worker);
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex);
      if (!error) error = std::current_exception();
    }
  };
  std::vector<std::thread> threads;
  threads.reserve(num_workers - 1);
  for (int worker = 1; worker < num_workers; ++worker) threads.emplace_back(run, worker);
  run(0);
  for (std::thread& thread : threads) thread.join();
  if (error) std::rethrow_exception(error);
}

int64_t FillHoles(RenderBuffers* buffers,
                  int iterations,
                  int radius_px,
                  double see_through_ratio,
                  int num_threads) {
  if (iterations <= 0 || buffers->height == 0) return 0;
  const int width = buffers->width;
  const int height = buffers->height;
  const int channels = buffers->channels;
  PaddedDepth depth;
  depth.radius = radius_px;
  depth.width = width + 2 * radius_px;
  depth.values.assign(static_cast<size_t>(depth.width) * (height + 2 * radius_px), kInfinity);
  std::vector<float> attributes(buffers->attributes.size());
  const float threshold_factor = static_cast<float>(1.0 / (1.0 + see_through_ratio));
  int64_t filled = 0;
  for (int pass = 0; pass < iterations; ++pass) {
    ParallelFor(num_threads, height, [&](int64_t begin, int64_t end, int) {
      for (int64_t y = begin; y < end; ++y) {
        const float* in = buffers->depth.data() + y * width;
        float* out = depth.values.data() + (y + radius_px) * depth.width + radius_px;
        for (int x = 0; x < width; ++x) out[x] = in[x] > 0.0f ? in[x] : kInfinity;
      }
    });
    attributes.swap(buffers->attributes);
    std::vector<int64_t> filled_per_worker(num_threads, 0);
    ParallelFor(num_threads, height, [&](int64_t begin, int64_t end, int worker) {
      filled_per_worker[worker] =
          FillRows(depth, attributes.data(), width, channels, threshold_factor,
                   static_cast<int>(begin), static_cast<int>(end), buffers->depth.data(),
                   buffers->attributes.data(), buffers->index.data());
    });
    int64_t filled_in_pass = 0;
    for (const int64_t n : filled_per_worker) filled_in_pass += n;
    filled += filled_in_pass;
    if (filled_in_pass == 0) break;
  }
  return filled;
}

}  // namespace render_internal
}  // namespace epiloc
