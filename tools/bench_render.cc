// Benchmark of the point-cloud renderer (cloud/render.h): a procedural street cloud (road with
// markings, pavements, building fronts with windows, poles; 10 million points by default) is
// rendered into a KITTI-like 1242x375 camera (fx 721) standing in the street, N times per thread
// count; prints ms per view (median, min) and the peak resident memory. A benchmark, not a test.
//
// Usage: epiloc_bench_render [--points N] [--repeats R] [--threads 1,2] [--shuffle]
//                            [--seed S] [--png FILE]
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "epiloc/cloud/render.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

struct BenchOptions {
  int64_t num_points = 10000000;
  int repeats = 10;
  std::vector<int> threads = {1, 2};
  bool shuffle = false;  // random point order (worst case for the z-buffer's caches)
  uint64_t seed = 1;
  std::string png;  // write the 2-thread rendering here
};

enum class Pattern { kRoad, kPavement, kFacade, kPole };

// A rectangle origin + [0, width] * u + [0, height] * v, or a vertical cylinder (kPole:
// origin = foot, width = radius, height).
struct Patch {
  Pattern pattern;
  Eigen::Vector3f origin;
  Eigen::Vector3f u;
  Eigen::Vector3f v;
  float width;
  float height;
  float Area() const {
    return pattern == Pattern::kPole ? 2.0f * 3.14159265f * width * height : width * height;
  }
};

// Intensity in [0, 1] of a point at patch coordinates (a, b) metres.
float Intensity(Pattern pattern, float a, float b, std::mt19937_64* rng) {
  std::uniform_real_distribution<float> jitter(-0.05f, 0.05f);
  float base = 0.3f;
  switch (pattern) {
    case Pattern::kRoad: {
      // Lane lines across the 14 m road: dashed centre line, solid edge lines.
      const bool centre = std::abs(b - 7.0f) < 0.08f && std::fmod(a + 1000.0f, 9.0f) < 3.0f;
      const bool edge = std::abs(b - 0.5f) < 0.08f || std::abs(b - 13.5f) < 0.08f;
      base = centre || edge ? 0.9f : 0.25f;
      break;
    }
    case Pattern::kPavement:
      base = std::fmod(a + 1000.0f, 0.6f) < 0.03f ? 0.3f : 0.5f;
      break;
    case Pattern::kFacade: {
      // Windows 1.2 m x 1.5 m on a 3 m x 3 m grid above the ground floor.
      const float x = std::fmod(a, 3.0f), y = std::fmod(b, 3.0f);
      const bool window = b > 3.0f && x > 0.9f && x < 2.1f && y > 0.8f && y < 2.3f;
      base = window ? 0.12f : 0.62f;
      break;
    }
    case Pattern::kPole:
      base = 0.7f;
      break;
  }
  return std::clamp(base + jitter(*rng), 0.0f, 1.0f);
}

std::vector<Patch> StreetPatches(std::mt19937_64* rng) {
  const Eigen::Vector3f east(1, 0, 0), north(0, 1, 0), up(0, 0, 1);
  const float x0 = -120.0f, length = 240.0f;
  std::vector<Patch> patches;
  patches.push_back({Pattern::kRoad, {x0, -7, 0}, east, north, length, 14});
  patches.push_back({Pattern::kPavement, {x0, 7, 0.15f}, east, north, length, 3});
  patches.push_back({Pattern::kPavement, {x0, -10, 0.15f}, east, north, length, 3});
  std::uniform_real_distribution<float> width(10, 25), height(8, 20), setback(0, 2);
  for (const float side : {1.0f, -1.0f}) {
    for (float x = x0; x < x0 + length;) {
      const float w = std::min(width(*rng), x0 + length - x);
      const float y = side * (10 + setback(*rng));
      patches.push_back({Pattern::kFacade, {x, y, 0.15f}, east, up, w, height(*rng)});
      x += w;
    }
    for (float x = x0 + 5; x < x0 + length; x += 25) {
      patches.push_back({Pattern::kPole, {x, side * 7.6f, 0.15f}, east, up, 0.12f, 8});
    }
  }
  return patches;
}

// Points on jittered grids over the patches, as many per patch as its share of the area.
PointCloud StreetCloud(const BenchOptions& options) {
  std::mt19937_64 rng(options.seed);
  const std::vector<Patch> patches = StreetPatches(&rng);
  double total_area = 0;
  for (const Patch& p : patches) total_area += p.Area();
  PointCloud cloud;
  cloud.positions.reserve(options.num_points);
  cloud.intensity.reserve(options.num_points);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  double area_done = 0;
  for (const Patch& p : patches) {
    area_done += p.Area();
    const int64_t target = std::llround(options.num_points * area_done / total_area);
    const int64_t count = target - static_cast<int64_t>(cloud.size());
    if (count <= 0) continue;
    const float along = p.pattern == Pattern::kPole ? 2 * 3.14159265f * p.width : p.width;
    const int64_t columns =
        std::max<int64_t>(1, static_cast<int64_t>(std::ceil(std::sqrt(count * along / p.height))));
    const int64_t rows = (count + columns - 1) / columns;
    for (int64_t i = 0; i < count; ++i) {
      const float a = (i % columns + unit(rng)) / columns * along;
      const float b = (i / columns + unit(rng)) / rows * p.height;
      Eigen::Vector3f x;
      if (p.pattern == Pattern::kPole) {
        const float angle = a / p.width;
        x = p.origin + p.width * Eigen::Vector3f(std::cos(angle), std::sin(angle), 0) + b * p.v;
      } else {
        x = p.origin + a * p.u + b * p.v + noise(rng) * p.u.cross(p.v);
      }
      cloud.positions.push_back(x);
      cloud.intensity.push_back(Intensity(p.pattern, a, b, &rng));
    }
  }
  if (options.shuffle) {
    std::vector<uint32_t> order(cloud.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<uint32_t>(i);
    std::shuffle(order.begin(), order.end(), rng);
    PointCloud shuffled;
    shuffled.positions.resize(cloud.size());
    shuffled.intensity.resize(cloud.size());
    for (size_t i = 0; i < order.size(); ++i) {
      shuffled.positions[i] = cloud.positions[order[i]];
      shuffled.intensity[i] = cloud.intensity[order[i]];
    }
    cloud = std::move(shuffled);
  }
  return cloud;
}

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // kilobytes on Linux
}

BenchOptions ParseArgs(int argc, char** argv) {
  BenchOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      EPILOC_CHECK(i + 1 < argc, "{} needs a value", arg);
      return argv[++i];
    };
    if (arg == "--points") {
      options.num_points = std::stoll(value());
    } else if (arg == "--repeats") {
      options.repeats = std::stoi(value());
    } else if (arg == "--threads") {
      options.threads.clear();
      const std::string list = value();
      for (size_t start = 0; start < list.size();) {
        const size_t comma = std::min(list.find(',', start), list.size());
        options.threads.push_back(std::stoi(list.substr(start, comma - start)));
        start = comma + 1;
      }
    } else if (arg == "--shuffle") {
      options.shuffle = true;
    } else if (arg == "--seed") {
      options.seed = std::stoull(value());
    } else if (arg == "--png") {
      options.png = value();
    } else {
      Throw("unknown argument '{}' (see the comment at the top of tools/bench_render.cc)", arg);
    }
  }
  EPILOC_CHECK(options.num_points > 0 && options.repeats > 0 && !options.threads.empty(),
               "need --points > 0, --repeats > 0 and at least one thread count");
  return options;
}

int Run(int argc, char** argv) {
  const BenchOptions bench = ParseArgs(argc, argv);
  const auto start = std::chrono::steady_clock::now();
  const PointCloud cloud = StreetCloud(bench);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cloud_mb =
      (cloud.positions.size() * sizeof(Eigen::Vector3f) + cloud.intensity.size() * sizeof(float)) /
      1048576.0;
  std::printf("cloud: %zu points%s (%.0f MB), generated in %.1f s; peak RSS %.0f MB\n",
              cloud.size(), bench.shuffle ? ", shuffled" : "", cloud_mb, seconds, PeakRssMb());

  // KITTI's rectified camera 0, 1.65 m above the right lane, looking east along the street.
  Camera camera;
  camera.width = 1242;
  camera.height = 375;
  camera.fx = camera.fy = 721.5377;
  camera.cx = 609.5593;
  camera.cy = 172.854;
  Eigen::Matrix3d world_from_cam_rotation;
  world_from_cam_rotation.col(0) = -Eigen::Vector3d::UnitY();  // camera x: right = south
  world_from_cam_rotation.col(1) = -Eigen::Vector3d::UnitZ();  // camera y: down
  world_from_cam_rotation.col(2) = Eigen::Vector3d::UnitX();   // camera z: forward = east
  const Rigid3d world_from_cam =
      Rigid3d::FromMatrix(world_from_cam_rotation, Eigen::Vector3d(0.0, -3.5, 1.65));
  const Rigid3d cam_from_world = world_from_cam.Inverse();

  CloudRenderOptions options;
  std::printf("view: %dx%d, fx %.1f; splat %.2f m (max %d px), %d hole-filling passes\n",
              camera.width, camera.height, camera.fx, options.splat_size_m, options.max_splat_px,
              options.hole_fill_iterations);
  for (const int threads : bench.threads) {
    options.num_threads = threads;
    CloudRenderResult result = RenderCloud(cloud, camera, cam_from_world, options);  // warm-up
    std::vector<double> ms;
    for (int r = 0; r < bench.repeats; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      result = RenderCloud(cloud, camera, cam_from_world, options);
      ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(ms.begin(), ms.end());
    std::printf(
        "threads %d: %.1f ms per view (median of %d), min %.1f ms; %lld points drawn, %d pixels "
        "covered, %lld filled\n",
        threads, ms[ms.size() / 2], bench.repeats, ms.front(),
        static_cast<long long>(result.points_drawn), cv::countNonZero(result.depth),
        static_cast<long long>(result.pixels_filled));
    if (!bench.png.empty() && threads == bench.threads.back()) {
      EPILOC_CHECK(cv::imwrite(bench.png, result.image), "{}: cannot write the image", bench.png);
      const std::string depth_png = bench.png.substr(0, bench.png.rfind('.')) + "_depth.png";
      EPILOC_CHECK(cv::imwrite(depth_png, ColouriseDepth(result.depth, 2.0, 120.0)),
                   "{}: cannot write the image", depth_png);
    }
  }
  std::printf("peak RSS %.0f MB (cloud %.0f MB)\n", PeakRssMb(), cloud_mb);
  return 0;
}

}  // namespace
}  // namespace epiloc

int main(int argc, char** argv) {
  try {
    return epiloc::Run(argc, argv);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "epiloc_bench_render: %s\n", error.what());
    return 1;
  }
}
