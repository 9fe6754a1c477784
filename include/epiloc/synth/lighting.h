// Sunlight for the synthetic street: Lambertian shading with an ambient (sky) term and exact cast
// shadows of every raised surface (buildings, trees, hedges, poles, signs, parked and moving cars).
//
// A rendered point p on a surface with unit normal n (turned towards the camera) gets the factor
//   ambient + direct * max(0, n . sun) * lit(p)
// where sun is the unit direction towards the sun and lit(p) is 0 if the ray p + t * sun (t > 0)
// hits another surface, else 1. The ray test is exact (ray-quad intersection); its candidates come
// from a grid of the casters' projections along the sun direction onto the road plane (every
// point of one sun ray projects to the same grid point), built once per world and sun direction.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/synth/world.h"

namespace epiloc {

struct SunOptions {
  double azimuth_deg = 135.0;   // compass direction of the sun: clockwise from north (90 = east)
  double elevation_deg = 35.0;  // above the horizon, in [10, 90]
  // Sky light on every surface. 0.4 + 0.8 * sin(45 deg) = 0.97: a road in sunlight at 45 deg keeps
  // about the brightness of the unshaded rendering, and shadows are 2.4x darker than sunlit
  // ground, as photographs of sunny streets show (shadow/sun ratios of 2-4 after the camera's tone
  // curve).
  double ambient = 0.4;
  double direct = 0.8;  // sunlight on a surface facing the sun

  // Throws Error naming the first invalid field.
  void Check() const;
  // Unit vector towards the sun in world ENU (x east, y north, z up).
  Eigen::Vector3d DirectionInWorld() const;
};

// The sun over one world. Copies what it needs of the world (casters and surface normals); Shade()
// is const and may run concurrently.
class Lighting {
 public:
  Lighting(const World& world, const SunOptions& sun);

  const SunOptions& sun() const { return sun_; }
  const Eigen::Vector3d& direction_in_world() const { return direction_; }
  int num_world_surfaces() const { return num_world_surfaces_; }

  // True if the ray from `point_in_world` towards the sun hits a world surface other than
  // `surface` (an index into World::surfaces, or -1) or one of `extra` (surfaces posed for one
  // frame; extra[k] has index num_world_surfaces() + k).
  bool InShadow(const Eigen::Vector3d& point_in_world,
                int surface,
                const std::vector<Surface>* extra = nullptr) const;

  // Shades a rendering in place. `colour` (CV_32FC3), `ids` (CV_32S: surface index as in
  // InShadow, -1 for sky) and `inverse_depth` (CV_64F: 1/z) are images of the undistorted camera
  // `pinhole` at cam_from_world (x_cam = R * x_world + t); sky pixels are left alone.
  void Shade(const Camera& pinhole,
             const Rigid3d& cam_from_world,
             const std::vector<Surface>* extra,
             const cv::Mat& ids,
             const cv::Mat& inverse_depth,
             cv::Mat* colour) const;

  // A shadow caster: a quad with what the ray test needs (public for the implementation's helpers).
  struct Caster {
    int surface = -1;
    Eigen::Vector3d normal, origin, u, v;
    double offset = 0;
    std::array<Eigen::Vector3d, 4> edges;  // (a, b, c): a * u + b * v + c >= 0 inside
    Eigen::Vector2d lo, hi;                // bounds of its projection along the sun
  };

 private:
  SunOptions sun_;
  Eigen::Vector3d direction_;
  int num_world_surfaces_ = 0;
  // The ray test against the world's casters and the frame's `extra` casters.
  bool Occluded(const Eigen::Vector3d& point_in_world,
                int surface,
                const std::vector<Caster>& extra) const;

  std::vector<Eigen::Vector3d> normals_;  // of every world surface (unit, u x v)
  std::vector<double> offsets_;           // their planes: normal . x = offset
  std::vector<Caster> casters_;
  // Grid over the casters' projections: cell (i, j) covers origin + [i, i + 1) x [j, j + 1) cells.
  Eigen::Vector2d grid_origin_ = Eigen::Vector2d::Zero();
  double cell_m_ = 1.0;
  int grid_cols_ = 0, grid_rows_ = 0;
  std::vector<int> cell_start_;  // CSR: casters of cell c are cell_casters_[start[c], start[c+1])
  std::vector<int> cell_casters_;
};

}  // namespace epiloc
