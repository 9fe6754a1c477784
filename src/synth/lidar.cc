#include "epiloc/synth/lidar.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <thread>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// What ray casting needs of a surface, computed once per world.
struct CastSurface {
  int index = -1;
  Eigen::Vector3d normal, origin, u, v;
  double offset = 0;
  std::array<Eigen::Vector3d, 4> edges;  // (a, b, c): a * u + b * v + c >= 0 inside, metres
  Eigen::Vector3d centre;
  double radius = 0;
};

std::vector<CastSurface> PrepareSurfaces(const World& world) {
  std::vector<CastSurface> out;
  for (int i = 0; i < static_cast<int>(world.surfaces.size()); ++i) {
    const Surface& s = world.surfaces[i];
    if (s.texture < 0) continue;
    CastSurface c;
    c.index = i;
    c.normal = s.Normal();
    c.offset = s.PlaneOffset();
    c.origin = s.texture_origin_in_world;
    c.u = s.u_axis;
    c.v = s.v_axis;
    std::array<Eigen::Vector2d, 4> uv;
    c.centre = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) {
      uv[k] = s.TextureCoordinates(s.corners_in_world[k]);
      c.centre += 0.25 * s.corners_in_world[k];
    }
    for (int k = 0; k < 4; ++k)
      c.radius = std::max(c.radius, (s.corners_in_world[k] - c.centre).norm());
    double area = 0;
    for (int k = 0; k < 4; ++k)
      area += uv[k].x() * uv[(k + 1) % 4].y() - uv[k].y() * uv[(k + 1) % 4].x();
    const double orient = area >= 0 ? 1.0 : -1.0;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d e = (uv[(k + 1) % 4] - uv[k]).normalized() * orient;
      // cross(e, p - uv_k) = e.x * (p.y - uv_k.y) - e.y * (p.x - uv_k.x)
      c.edges[k] = Eigen::Vector3d(-e.y(), e.x(), e.y() * uv[k].x() - e.x() * uv[k].y());
    }
    out.push_back(c);
  }
  return out;
}

std::vector<LidarPoint> CastScan(const World& world,
                                 const std::vector<CastSurface>& surfaces,
                                 const Rigid3d& world_from_sensor,
                                 const LidarOptions& o,
                                 uint64_t noise_seed,
                                 int32_t scan_index) {
  const Eigen::Matrix3d r = world_from_sensor.rotation.toRotationMatrix();
  const Eigen::Vector3d origin = world_from_sensor.translation;
  const bool full = o.azimuth_fov_deg >= 360.0 - 1e-9;
  const int num_columns =
      static_cast<int>(std::floor(o.azimuth_fov_deg / o.azimuth_step_deg)) + (full ? 0 : 1);
  const double first_az = full ? -180.0 * kDegToRad : -0.5 * o.azimuth_fov_deg * kDegToRad;
  const double step = o.azimuth_step_deg * kDegToRad;
  // Candidate surfaces per azimuth column, from each surface's angular span seen from above.
  std::vector<std::vector<const CastSurface*>> columns(num_columns);
  for (const CastSurface& c : surfaces) {
    if ((c.centre - origin).norm() - c.radius > o.max_range_m) continue;
    const Surface& s = world.surfaces[c.index];
    std::array<Eigen::Vector2d, 4> xy;
    for (int k = 0; k < 4; ++k)
      xy[k] = (r.transpose() * (s.corners_in_world[k] - origin)).head<2>();
    // Does the sensor's vertical line pass through the quad's projection?
    bool inside = true;
    double area = 0;
    for (int k = 0; k < 4; ++k)
      area += xy[k].x() * xy[(k + 1) % 4].y() - xy[k].y() * xy[(k + 1) % 4].x();
    for (int k = 0; k < 4 && inside; ++k) {
      const Eigen::Vector2d e = xy[(k + 1) % 4] - xy[k];
      inside = (area >= 0 ? 1 : -1) * (e.x() * -xy[k].y() - e.y() * -xy[k].x()) >= 0;
    }
    int k0 = 0, k1 = num_columns - 1;
    if (!(inside && std::abs(area) > 1e-9)) {
      const double a0 = std::atan2(xy[0].y(), xy[0].x());
      double lo = 0, hi = 0;
      for (int k = 1; k < 4; ++k) {
        const double a = std::remainder(std::atan2(xy[k].y(), xy[k].x()) - a0, 2 * M_PI);
        lo = std::min(lo, a);
        hi = std::max(hi, a);
      }
      k0 = static_cast<int>(std::floor((a0 + lo - first_az) / step)) - 1;
      k1 = static_cast<int>(std::ceil((a0 + hi - first_az) / step)) + 1;
    }
    for (int k = k0; k <= k1; ++k) {
      int kk = k;
      if (full) {
        kk = ((k % num_columns) + num_columns) % num_columns;
      } else if (k < 0 || k >= num_columns) {
        continue;
      }
      columns[kk].push_back(&c);
      if (full && k1 - k0 + 1 >= num_columns) {
        for (int j = 0; j < num_columns; ++j) {
          if (j != kk) columns[j].push_back(&c);
        }
        break;
      }
    }
  }
  Rng rng(noise_seed);
  std::vector<LidarPoint> points;
  for (int k = 0; k < num_columns; ++k) {
    const double az = first_az + k * step;
    for (int ring = 0; ring < o.num_rings; ++ring) {
      const double el =
          (o.num_rings == 1 ? o.min_elevation_deg
                            : o.min_elevation_deg + (o.max_elevation_deg - o.min_elevation_deg) *
                                                        ring / (o.num_rings - 1)) *
          kDegToRad;
      const Eigen::Vector3d dir = r * Eigen::Vector3d(std::cos(el) * std::cos(az),
                                                      std::cos(el) * std::sin(az), std::sin(el));
      double best = o.max_range_m;
      const CastSurface* hit = nullptr;
      for (const CastSurface* c : columns[k]) {
        const double denom = c->normal.dot(dir);
        if (std::abs(denom) < 1e-12) continue;
        const double t = (c->offset - c->normal.dot(origin)) / denom;
        if (t < o.min_range_m || t >= best) continue;
        const Eigen::Vector3d p = origin + t * dir - c->origin;
        const double u = p.dot(c->u), v = p.dot(c->v);
        bool in = true;
        for (const Eigen::Vector3d& e : c->edges) in = in && e.x() * u + e.y() * v + e.z() >= -1e-9;
        if (!in) continue;
        best = t;
        hit = c;
      }
      const double noise = o.range_noise_m * rng.Normal();  // drawn for every beam: stable streams
      if (!hit) continue;
      const Surface& s = world.surfaces[hit->index];
      const Texture& texture = world.textures[s.texture];
      const Eigen::Vector2d uv = s.TextureCoordinates(origin + best * dir);
      const int tx = std::clamp(static_cast<int>(std::floor(uv.x() / texture.metres_per_pixel)), 0,
                                texture.image.cols - 1);
      const int ty = std::clamp(static_cast<int>(std::floor(uv.y() / texture.metres_per_pixel)), 0,
                                texture.image.rows - 1);
      const cv::Vec3b bgr = texture.image.at<cv::Vec3b>(ty, tx);
      LidarPoint point;
      point.position = (origin + (best + noise) * dir).cast<float>();
      point.intensity =
          static_cast<float>((0.114 * bgr[0] + 0.587 * bgr[1] + 0.299 * bgr[2]) / 255.0);
      point.rgb = {bgr[2], bgr[1], bgr[0]};
      point.surface = hit->index;
      point.scan = scan_index;
      points.push_back(point);
    }
  }
  return points;
}

}  // namespace

void LidarOptions::Check() const {
  EPILOC_CHECK(scan_spacing_m > 0, "lidar options: scan_spacing_m must be positive");
  EPILOC_CHECK(std::isfinite(sensor_height_m), "lidar options: sensor_height_m is not finite");
  EPILOC_CHECK(num_rings >= 1, "lidar options: num_rings must be >= 1");
  EPILOC_CHECK(
      min_elevation_deg <= max_elevation_deg && min_elevation_deg > -90 && max_elevation_deg < 90,
      "lidar options: elevations must satisfy -90 < min <= max < 90");
  EPILOC_CHECK(azimuth_step_deg > 0, "lidar options: azimuth_step_deg must be positive");
  EPILOC_CHECK(azimuth_fov_deg > 0 && azimuth_fov_deg <= 360,
               "lidar options: azimuth_fov_deg must be in (0, 360]");
  EPILOC_CHECK(max_range_m > min_range_m && min_range_m >= 0,
               "lidar options: need 0 <= min_range_m < max_range_m");
  EPILOC_CHECK(range_noise_m >= 0, "lidar options: range_noise_m must not be negative");
  EPILOC_CHECK(num_threads >= 1, "lidar options: num_threads must be >= 1");
}

std::vector<LidarPoint> SimulateScan(const World& world,
                                     const Rigid3d& world_from_sensor,
                                     const LidarOptions& options,
                                     uint64_t noise_seed,
                                     int32_t scan_index) {
  options.Check();
  return CastScan(world, PrepareSurfaces(world), world_from_sensor, options, noise_seed,
                  scan_index);
}

std::vector<LidarPoint> SimulateScans(const World& world,
                                      const std::vector<Rigid3d>& world_from_sensor,
                                      const LidarOptions& options,
                                      uint64_t seed,
                                      const ProgressCallback& progress) {
  options.Check();
  const std::vector<CastSurface> surfaces = PrepareSurfaces(world);
  const int n = static_cast<int>(world_from_sensor.size());
  std::vector<std::vector<LidarPoint>> scans(n);
  std::vector<std::exception_ptr> errors(n);
  std::atomic<int> next{0};
  std::mutex mutex;
  int64_t done = 0;
  const auto work = [&] {
    for (int i = next++; i < n; i = next++) {
      try {
        scans[i] = CastScan(world, surfaces, world_from_sensor[i], options, MixSeed(seed, i), i);
      } catch (...) {
        errors[i] = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(mutex);
      ++done;
      if (progress) progress(done, n);
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < options.num_threads; ++t) threads.emplace_back(work);
  work();
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  std::vector<LidarPoint> all;
  size_t total = 0;
  for (const auto& scan : scans) total += scan.size();
  all.reserve(total);
  for (auto& scan : scans) all.insert(all.end(), scan.begin(), scan.end());
  return all;
}

}  // namespace epiloc
