#include "epiloc/cloud/render.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "render_internal.h"

namespace epiloc {

using render_internal::kEmptyKey;
using render_internal::KeyDepth;
using render_internal::KeyIndex;
using render_internal::PackKey;
using render_internal::ParallelFor;
using render_internal::RenderBuffers;

namespace {

// The camera applied to x - origin in float: rows give a = (u + 0.5) z, b = (v + 0.5) z and z,
// so the pixel of a point is (floor(a / z), floor(b / z)) = (round(u), round(v)).
struct Projection {
  float origin[3];
  float m[3][4];
};

Projection MakeProjection(const Camera& camera, const Rigid3d& cam_from_world) {
  const Eigen::Matrix3d r = cam_from_world.rotation.toRotationMatrix();
  // Positions far from the ENU origin lose digits in R x + t; x - origin with the origin at the
  // camera centre (as a float, so the subtraction is exact for points near it) keeps them.
  const Eigen::Vector3f origin = (-(r.transpose() * cam_from_world.translation)).cast<float>();
  Eigen::Matrix<double, 3, 4> rt;
  rt << r, r * origin.cast<double>() + cam_from_world.translation;
  Eigen::Matrix<double, 3, 4> p;
  p.row(0) = camera.fx * rt.row(0) + (camera.cx + 0.5) * rt.row(2);
  p.row(1) = camera.fy * rt.row(1) + (camera.cy + 0.5) * rt.row(2);
  p.row(2) = rt.row(2);
  Projection projection;
  for (int i = 0; i < 3; ++i) {
    projection.origin[i] = origin[i];
    for (int j = 0; j < 4; ++j) projection.m[i][j] = static_cast<float>(p(i, j));
  }
  return projection;
}

static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "Vector3f must be packed");

// Projects and culls n points (x y z packed floats): pixels[k] = row * width + column of point
// k, or -1 if culled; depths[k] = its depth. Returns the number not culled. Branch-free so that the
// compiler vectorises it: the x86-64 baseline (SSE2) lacks the shuffles and integer multiplies for
// that, so an AVX2 clone is chosen at load time where the CPU has it. Both compute the same IEEE
// results.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
int ProjectBlock(const float* xyz,
                  int n,
                  const Projection& p,
                  float near_m,
                  float far_m,
                  int width,
                  int height,
                  int32_t* __restrict pixels,
                  float* __restrict depths) {
  const float w = static_cast<float>(width);
  const float h = static_cast<float>(height);
  // Locals, so the compiler need not reload them after each store.
  const float ox = p.origin[0], oy = p.origin[1], oz = p.origin[2];
  const float a0 = p.m[0][0], a1 = p.m[0][1], a2 = p.m[0][2], a3 = p.m[0][3];
  const float b0 = p.m[1][0], b1 = p.m[1][1], b2 = p.m[1][2], b3 = p.m[1][3];
  const float c0 = p.m[2][0], c1 = p.m[2][1], c2 = p.m[2][2], c3 = p.m[2][3];
  int num_visible = 0;
  for (int k = 0; k < n; ++k) {
    const float x = xyz[3 * k] - ox;
    const float y = xyz[3 * k + 1] - oy;
    const float z = xyz[3 * k + 2] - oz;
    const float depth = c0 * x + c1 * y + c2 * z + c3;
    const float inverse_depth = 1.0f / depth;
    const float u = (a0 * x + a1 * y + a2 * z + a3) * inverse_depth;
    const float v = (b0 * x + b1 * y + b2 * z + b3) * inverse_depth;
    // Comparisons with NaN are false: NaN positions are culled too.
    const bool visible =
        (depth >= near_m) & (depth <= far_m) & (u >= 0.0f) & (u < w) & (v >= 0.0f) & (v < h);
    const int column = static_cast<int>(visible ? u : 0.0f);
    const int row = static_cast<int>(visible ? v : 0.0f);
    pixels[k] = visible ? row * width + column : -1;
    depths[k] = depth;
    num_visible += visible;
  }
  return num_visible;
}

// Draws points [begin, end) as single pixels into `zbuffer` (keys, kEmptyKey = empty) and
// returns how many passed culling. Splats are added afterwards (ExpandSplats): the nearest point
// of a pixel has the largest splat there and covers the splat of every farther point of the
// pixel, so splatting only the winner of each pixel gives exactly the full splatting result at
// a cost bounded by the image size instead of the overdraw.
int64_t DrawPoints(const Eigen::Vector3f* positions,
                   int64_t begin,
                   int64_t end,
                   const Projection& projection,
                   float near_m,
                   float far_m,
                   int width,
                   int height,
                   uint64_t* zbuffer) {
  constexpr int kBlock = 256;
  int32_t pixels[kBlock];
  float depths[kBlock];
  int64_t drawn = 0;
  for (int64_t first = begin; first < end; first += kBlock) {
    const int n = static_cast<int>(std::min<int64_t>(kBlock, end - first));
    // Vector3f is three packed floats: the block is one float array.
    const int num_visible = ProjectBlock(positions[first].data(), n, projection, near_m, far_m,
                                         width, height, pixels, depths);
    if (num_visible == 0) continue;  // common: maps are ordered in space, views see a part
    drawn += num_visible;
    for (int k = 0; k < n; ++k) {
      if (pixels[k] < 0) continue;
      const uint64_t key = PackKey(depths[k], static_cast<uint32_t>(first + k));
      uint64_t& slot = zbuffer[pixels[k]];
      slot = std::min(slot, key);  // a store every time, but no mispredicted branch
    }
  }
  return drawn;
}

// Side of a splat in pixels: the odd number nearest splat_px_m / depth_m, clamped to
// [1, max_splat_px] (max_splat_px itself if it is the limit, even or not). Odd sides keep a
// splat centred on its point's pixel: an even side cannot be, and would shift the rendering by
// half a pixel up and left against the depth (a bias of centimetres in a pose solved from it).
inline int SplatSide(float depth_m, float splat_px_m, int max_splat_px) {
  const float side = splat_px_m / depth_m;
  if (side >= static_cast<float>(max_splat_px)) return max_splat_px;
  return std::min(max_splat_px, 1 + 2 * std::max(0, static_cast<int>((side - 1.0f) * 0.5f + 0.5f)));
}

// Writes rows [row_begin, row_end) of `splats`: the nearest key of all splats of the pixel
// winners in `points` that cover each pixel. (The AVX2 clone vectorises the rows of a splat.)
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
void ExpandSplats(const uint64_t* points,
                  uint64_t* splats,
                  int width,
                  int height,
                  float splat_px_m,
                  int max_splat_px,
                  int row_begin,
                  int row_end) {
  std::fill(splats + static_cast<int64_t>(row_begin) * width,
            splats + static_cast<int64_t>(row_end) * width, kEmptyKey);
  // A splat of side s centred on row y covers rows [y - s/2, y - s/2 + s).
  const int first_row = std::max(0, row_begin - (max_splat_px - 1) / 2);
  const int end_row = std::min(height, row_end + max_splat_px / 2);
  for (int y = first_row; y < end_row; ++y) {
    const uint64_t* row = points + static_cast<int64_t>(y) * width;
    for (int x = 0; x < width; ++x) {
      const uint64_t key = row[x];
      if (key == kEmptyKey) continue;
      const int side = SplatSide(KeyDepth(key), splat_px_m, max_splat_px);
      const int y0 = std::max(row_begin, y - side / 2);
      const int y1 = std::min(row_end, y - side / 2 + side);
      const int x0 = std::max(0, x - side / 2);
      const int x1 = std::min(width, x - side / 2 + side);
      for (int yy = y0; yy < y1; ++yy) {
        uint64_t* out = splats + static_cast<int64_t>(yy) * width;
        for (int xx = x0; xx < x1; ++xx) out[xx] = std::min(out[xx], key);
      }
    }
  }
}

RenderShading ResolveShading(RenderShading shading, const PointCloud& cloud) {
  switch (shading) {
    case RenderShading::kAuto:
      return cloud.HasColour()      ? RenderShading::kColour
             : cloud.HasIntensity() ? RenderShading::kIntensity
                                    : RenderShading::kDepth;
    case RenderShading::kIntensity:
      EPILOC_CHECK(cloud.HasIntensity(),
                   "cloud render: shading 'intensity' needs a cloud with intensity");
      return shading;
    case RenderShading::kColour:
      EPILOC_CHECK(cloud.HasColour(), "cloud render: shading 'colour' needs a cloud with colour");
      return shading;
    case RenderShading::kDepth:
      return shading;
  }
  Throw("cloud render: unknown shading {}", static_cast<int>(shading));
}

void CheckCloud(const PointCloud& cloud) {
  // PointCloud::Check's rule, restated here so the renderer can name its own failure.
  EPILOC_CHECK(cloud.intensity.empty() || cloud.intensity.size() == cloud.size(),
               "cloud render: {} intensities for {} points", cloud.intensity.size(), cloud.size());
  EPILOC_CHECK(cloud.rgb.empty() || cloud.rgb.size() == cloud.size(),
               "cloud render: {} colours for {} points", cloud.rgb.size(), cloud.size());
  EPILOC_CHECK(cloud.size() <= static_cast<size_t>(std::numeric_limits<int32_t>::max()),
               "cloud render: {} points, at most 2^31 - 1 can be rendered", cloud.size());
}

// Fills rows [row_begin, row_end) of `buffers` from the z-buffer of splats.
void Resolve(const uint64_t* splats,
             const PointCloud& cloud,
             int64_t pixel_begin,
             int64_t pixel_end,
             RenderBuffers* buffers) {
  const int channels = buffers->channels;
  for (int64_t pixel = pixel_begin; pixel < pixel_end; ++pixel) {
    const uint64_t key = splats[pixel];
    float* attributes = buffers->attributes.data() + pixel * channels;
    if (key == kEmptyKey) {
      buffers->depth[pixel] = 0.0f;
      buffers->index[pixel] = -1;
      std::fill(attributes, attributes + channels, 0.0f);
      continue;
    }
    const uint32_t index = KeyIndex(key);
    buffers->depth[pixel] = KeyDepth(key);
    buffers->index[pixel] = static_cast<int32_t>(index);
    if (channels == 1) {
      attributes[0] = cloud.intensity[index];
    } else if (channels == 3) {
      for (int c = 0; c < 3; ++c) attributes[c] = cloud.rgb[index][c];
    }
  }
}

// Grey image of the intensity; equalised over the covered pixels (mid-rank of a 1024-bin
// histogram) so the rendering uses the full grey range as a camera image does.
cv::Mat ShadeIntensity(const RenderBuffers& buffers, bool equalize) {
  cv::Mat image(buffers.height, buffers.width, CV_8UC1, cv::Scalar(0));
  uint8_t* out = image.ptr<uint8_t>();
  const int64_t num_pixels = static_cast<int64_t>(buffers.width) * buffers.height;
  constexpr int kBins = 1024;
  auto bin = [](float intensity) {
    const float scaled = intensity * kBins;
    if (!(scaled > 0.0f)) return 0;  // also NaN
    return scaled >= kBins ? kBins - 1 : static_cast<int>(scaled);
  };
  std::array<uint8_t, kBins> grey_of_bin;
  if (equalize) {
    std::array<int64_t, kBins> histogram{};
    int64_t covered = 0;
    for (int64_t pixel = 0; pixel < num_pixels; ++pixel) {
      if (buffers.depth[pixel] > 0.0f) {
        ++histogram[bin(buffers.attributes[pixel])];
        ++covered;
      }
    }
    int64_t below = 0;
    for (int i = 0; i < kBins; ++i) {
      const double rank = (below + 0.5 * histogram[i]) / std::max<int64_t>(covered, 1);
      grey_of_bin[i] = static_cast<uint8_t>(std::lround(1.0 + 254.0 * rank));
      below += histogram[i];
    }
  } else {
    for (int i = 0; i < kBins; ++i) {
      grey_of_bin[i] = static_cast<uint8_t>(std::lround(255.0 * (i + 0.5) / kBins));
    }
  }
  for (int64_t pixel = 0; pixel < num_pixels; ++pixel) {
    if (buffers.depth[pixel] > 0.0f) out[pixel] = grey_of_bin[bin(buffers.attributes[pixel])];
  }
  return image;
}

cv::Mat ShadeColour(const RenderBuffers& buffers) {
  cv::Mat image(buffers.height, buffers.width, CV_8UC3, cv::Scalar::all(0));
  uint8_t* out = image.ptr<uint8_t>();
  const int64_t num_pixels = static_cast<int64_t>(buffers.width) * buffers.height;
  for (int64_t pixel = 0; pixel < num_pixels; ++pixel) {
    if (!(buffers.depth[pixel] > 0.0f)) continue;
    const float* rgb = buffers.attributes.data() + 3 * pixel;
    for (int c = 0; c < 3; ++c) out[3 * pixel + c] = cv::saturate_cast<uint8_t>(rgb[2 - c]);
  }
  return image;
}

// Log depth between near (255) and far (1); empty pixels 0.
cv::Mat ShadeDepth(const RenderBuffers& buffers, double near_m, double far_m) {
  cv::Mat image(buffers.height, buffers.width, CV_8UC1, cv::Scalar(0));
  uint8_t* out = image.ptr<uint8_t>();
  const int64_t num_pixels = static_cast<int64_t>(buffers.width) * buffers.height;
  const double scale = 254.0 / std::log(far_m / near_m);
  for (int64_t pixel = 0; pixel < num_pixels; ++pixel) {
    const float z = buffers.depth[pixel];
    if (!(z > 0.0f)) continue;
    out[pixel] = cv::saturate_cast<uint8_t>(1.0 + scale * std::log(far_m / z));
  }
  return image;
}

}  // namespace

const char* RenderShadingName(RenderShading shading) {
  switch (shading) {
    case RenderShading::kAuto:
      return "auto";
    case RenderShading::kIntensity:
      return "intensity";
    case RenderShading::kColour:
      return "colour";
    case RenderShading::kDepth:
      return "depth";
  }
  return "unknown";
}

void CloudRenderOptions::Check() const {
  EPILOC_CHECK(std::isfinite(near_m) && near_m > 0,
               "cloud render options: near_m = {} must be positive", near_m);
  EPILOC_CHECK(std::isfinite(far_m) && far_m > near_m,
               "cloud render options: far_m = {} must be finite and greater than near_m = {}",
               far_m, near_m);
  EPILOC_CHECK(std::isfinite(splat_size_m) && splat_size_m >= 0,
               "cloud render options: splat_size_m = {} must not be negative", splat_size_m);
  EPILOC_CHECK(max_splat_px >= 1 && max_splat_px <= 64,
               "cloud render options: max_splat_px = {} must be in [1, 64]", max_splat_px);
  EPILOC_CHECK(hole_fill_iterations >= 0,
               "cloud render options: hole_fill_iterations = {} must not be negative",
               hole_fill_iterations);
  EPILOC_CHECK(hole_fill_radius_px >= 1 && hole_fill_radius_px <= 32,
               "cloud render options: hole_fill_radius_px = {} must be in [1, 32]",
               hole_fill_radius_px);
  EPILOC_CHECK(std::isfinite(see_through_ratio) && see_through_ratio > 0,
               "cloud render options: see_through_ratio = {} must be positive", see_through_ratio);
  EPILOC_CHECK(num_threads >= 1 && num_threads <= 256,
               "cloud render options: num_threads = {} must be in [1, 256]", num_threads);
  EPILOC_CHECK(shading == RenderShading::kAuto || shading == RenderShading::kIntensity ||
                   shading == RenderShading::kColour || shading == RenderShading::kDepth,
               "cloud render options: unknown shading {}", static_cast<int>(shading));
}

CloudRenderResult RenderCloud(const PointCloud& cloud,
                              const Camera& camera,
                              const Rigid3d& cam_from_world,
                              const CloudRenderOptions& options) {
  options.Check();
  camera.Check("cloud render: camera");
  CheckCloud(cloud);
  CloudRenderResult result;
  result.shading = ResolveShading(options.shading, cloud);
  const int width = camera.width;
  const int height = camera.height;
  const int64_t num_pixels = static_cast<int64_t>(width) * height;
  const int num_threads = options.num_threads;

  // Points as single pixels, each worker into its own z-buffer, merged by minimum.
  const Projection projection = MakeProjection(camera, cam_from_world);
  std::vector<std::vector<uint64_t>> zbuffers(num_threads);
  std::vector<int64_t> drawn(num_threads, 0);
  ParallelFor(
      num_threads, static_cast<int64_t>(cloud.size()), [&](int64_t begin, int64_t end, int worker) {
        zbuffers[worker].assign(num_pixels, kEmptyKey);
        drawn[worker] = DrawPoints(
            cloud.positions.data(), begin, end, projection, static_cast<float>(options.near_m),
            static_cast<float>(options.far_m), width, height, zbuffers[worker].data());
      });
  std::vector<uint64_t>& points = zbuffers[0];
  for (int w = 0; w < num_threads; ++w) result.points_drawn += drawn[w];
  ParallelFor(num_threads, num_pixels, [&](int64_t begin, int64_t end, int) {
    for (int w = 1; w < num_threads && !zbuffers[w].empty(); ++w) {
      const uint64_t* other = zbuffers[w].data();
      for (int64_t pixel = begin; pixel < end; ++pixel) {
        points[pixel] = std::min(points[pixel], other[pixel]);
      }
    }
  });
  for (int w = 1; w < num_threads; ++w) std::vector<uint64_t>().swap(zbuffers[w]);

  const float splat_px_m = static_cast<float>(options.splat_size_m * camera.fx);
  std::vector<uint64_t> splats;
  if (options.max_splat_px > 1 && splat_px_m / options.near_m >= 1.5) {
    splats.resize(num_pixels);
    ParallelFor(num_threads, height, [&](int64_t begin, int64_t end, int) {
      ExpandSplats(points.data(), splats.data(), width, height, splat_px_m, options.max_splat_px,
                   static_cast<int>(begin), static_cast<int>(end));
    });
  } else {
    splats.swap(points);  // every splat is a single pixel
  }

  RenderBuffers buffers;
  buffers.width = width;
  buffers.height = height;
  buffers.channels = result.shading == RenderShading::kIntensity ? 1
                     : result.shading == RenderShading::kColour  ? 3
                                                                 : 0;
  buffers.depth.resize(num_pixels);
  buffers.index.resize(num_pixels);
  buffers.attributes.resize(num_pixels * buffers.channels);
  ParallelFor(num_threads, num_pixels, [&](int64_t begin, int64_t end, int) {
    Resolve(splats.data(), cloud, begin, end, &buffers);
  });

  result.pixels_filled = render_internal::FillHoles(&buffers, options.hole_fill_iterations,
                                                    options.hole_fill_radius_px,
                                                    options.see_through_ratio, num_threads);

  switch (result.shading) {
    case RenderShading::kIntensity:
      result.image = ShadeIntensity(buffers, options.intensity_equalize);
      break;
    case RenderShading::kColour:
      result.image = ShadeColour(buffers);
      break;
    default:
      result.image = ShadeDepth(buffers, options.near_m, options.far_m);
      break;
  }
  result.depth = cv::Mat(height, width, CV_32F, buffers.depth.data()).clone();
  result.point_index = cv::Mat(height, width, CV_32S, buffers.index.data()).clone();
  return result;
}

bool LiftPixel(const CloudRenderResult& render,
               const Camera& camera,
               const Rigid3d& cam_from_world,
               double u,
               double v,
               Eigen::Vector3d* point_in_world) {
  EPILOC_CHECK(render.depth.type() == CV_32F && render.depth.cols == camera.width &&
                   render.depth.rows == camera.height,
               "lift pixel: the rendering's depth is not a CV_32F {}x{} image", camera.width,
               camera.height);
  if (!(std::isfinite(u) && std::isfinite(v))) return false;
  const double x = std::round(u);
  const double y = std::round(v);
  if (x < 0 || y < 0 || x >= camera.width || y >= camera.height) return false;
  const float z = render.depth.at<float>(static_cast<int>(y), static_cast<int>(x));
  if (!(z > 0.0f)) return false;
  const Eigen::Vector3d point_in_cam((u - camera.cx) / camera.fx * z,
                                     (v - camera.cy) / camera.fy * z, z);
  *point_in_world = cam_from_world.Inverse() * point_in_cam;
  return true;
}

cv::Mat ColouriseDepth(const cv::Mat& depth, double near_m, double far_m) {
  EPILOC_CHECK(depth.type() == CV_32F, "colourise depth: the depth image must be CV_32F");
  EPILOC_CHECK(near_m > 0 && far_m > near_m,
               "colourise depth: need 0 < near_m < far_m (got {}, {})", near_m, far_m);
  cv::Mat grey(depth.size(), CV_8UC1);
  const double inverse_far = 1.0 / far_m;
  const double scale = 255.0 / (1.0 / near_m - inverse_far);
  for (int y = 0; y < depth.rows; ++y) {
    const float* in = depth.ptr<float>(y);
    uint8_t* out = grey.ptr<uint8_t>(y);
    for (int x = 0; x < depth.cols; ++x) {
      out[x] = in[x] > 0.0f ? cv::saturate_cast<uint8_t>(scale * (1.0 / in[x] - inverse_far)) : 0;
    }
  }
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_TURBO);
  colour.setTo(cv::Scalar::all(0), depth <= 0.0f);
  return colour;
}

}  // namespace epiloc
