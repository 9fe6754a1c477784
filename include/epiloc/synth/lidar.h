// A simulated mobile-mapping LiDAR: spinning multi-beam scans taken along the survey path,
// each beam intersected exactly with the world's quads (nearest hit), with range noise and the
// texture's grey value as intensity. Point density falls off with range as in a real scanner.
//
// Sensor frame: x forward, y left, z up (as KITTI's Velodyne).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/core/progress.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/synth/world.h"

namespace epiloc {

struct LidarOptions {
  double scan_spacing_m = 10.0;  // distance between scans along the survey path
  double sensor_height_m = 1.7;  // sensor above the road surface
  int num_rings = 64;            // beams, elevations evenly spaced in [min, max]
  double min_elevation_deg = -25.0;
  double max_elevation_deg = 3.0;
  double azimuth_step_deg = 0.2;   // angle between firings of a beam
  double azimuth_fov_deg = 180.0;  // horizontal field kept, centred on forward (360 = all)
  double max_range_m = 80.0;       // farther hits are dropped
  double min_range_m = 1.0;        // nearer hits are dropped (the vehicle itself)
  double range_noise_m = 0.02;     // Gaussian range noise, standard deviation
  int num_threads = 2;             // scans simulated in parallel (the result does not depend on it)

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct LidarPoint {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();  // world ENU (or sensor frame, see below)
  float intensity = 0.0f;                              // texture grey value at the hit, [0, 1]
  std::array<uint8_t, 3> rgb{};                        // texture colour at the hit
  int32_t surface = -1;                                // index into World::surfaces
  int32_t scan = -1;                                   // index of the scan that saw it
};

// One scan from the sensor pose world_from_sensor; points in world ENU with the noise applied.
// `noise_seed` makes the range noise reproducible.
std::vector<LidarPoint> SimulateScan(const World& world,
                                     const Rigid3d& world_from_sensor,
                                     const LidarOptions& options,
                                     uint64_t noise_seed,
                                     int32_t scan_index = 0);

// All scans (scan i from poses[i], noise seed derived from `seed` and i), concatenated in scan
// order. `progress` (optional) gets (scans done, scans total), from worker threads.
std::vector<LidarPoint> SimulateScans(const World& world,
                                      const std::vector<Rigid3d>& world_from_sensor,
                                      const LidarOptions& options,
                                      uint64_t seed,
                                      const ProgressCallback& progress = nullptr);

// Writes a binary little-endian PLY with properties x y z (float, metres), intensity (float),
// red green blue (uchar) (WritePointCloud of the cloud module). Points are transformed by
// `frame_from_world` first (identity: world ENU). Throws Error if the file cannot be written.
void WritePly(const std::string& path,
              const std::vector<LidarPoint>& points,
              const Rigid3d& frame_from_world = Rigid3d());
// Reads a PLY with positions, intensity and colour, as WritePly writes (ReadPointCloud of the
// cloud module: non-finite points are dropped; surface and scan are left at -1). Throws Error for
// a malformed or truncated file or one without intensity or colour.
std::vector<LidarPoint> ReadPly(const std::string& path);

}  // namespace epiloc
