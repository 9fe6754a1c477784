// Two-view geometry of the monocular odometry: relative pose from an essential matrix (the map's
// initialisation), triangulation of a point from two views, and its checks.
//
// All image positions are normalised camera coordinates (x/z, y/z of the ray in the camera
// frame: undistorted, intrinsics removed); thresholds are given in pixels and converted with the
// camera's focal length `focal_px`.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/geo/rigid3.h"

namespace epiloc {

struct TwoViewOptions {
  double focal_px = 500.0;               // converts the pixel thresholds to normalised units
  double max_error_px = 1.0;             // RANSAC threshold of the essential matrix (Sampson)
  double confidence = 0.999;             // RANSAC confidence
  int max_iterations = 2000;             // RANSAC iterations
  int min_inliers = 60;                  // of the essential matrix
  int min_points = 50;                   // triangulated with enough parallax
  double min_parallax_deg = 1.0;         // ray angle a point needs to count towards min_points
  double min_median_parallax_deg = 0.8;  // of all triangulated points: enough baseline overall
  double max_reprojection_px = 2.0;      // of a triangulated point in either view
  uint64_t seed = 1;                     // RANSAC random state (deterministic)

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct TwoViewResult {
  bool ok = false;
  std::string failure;  // why not, when !ok
  // Pose of the second camera: x_in_cam2 = R * x_in_cam1 + t, |t| = 1 (monocular: no scale).
  Rigid3d cam2_from_cam1;
  int num_inliers = 0;       // of the essential matrix, in front of both cameras
  int num_triangulated = 0;  // points with reprojection and parallax checks passed
  double median_parallax_deg = 0.0;
  // Per input correspondence: the point in camera 1 coordinates, when triangulated.
  std::vector<std::optional<Eigen::Vector3d>> points_in_cam1;
};

// Relative pose and points from correspondences `x1[i]` <-> `x2[i]` (normalised coordinates):
// five-point essential matrix in USAC RANSAC (OpenCV), cheirality, triangulation. Expected
// failure (too few inliers, too little parallax, e.g. a pure rotation) is reported in the result.
TwoViewResult EstimateTwoView(const std::vector<Eigen::Vector2d>& x1,
                              const std::vector<Eigen::Vector2d>& x2,
                              const TwoViewOptions& options);

// Point seen at normalised `x1` by camera 1 and `x2` by camera 2 (linear DLT triangulation, world
// frame). nullopt if the rays are (near) parallel.
std::optional<Eigen::Vector3d> TriangulatePoint(const Rigid3d& cam1_from_world,
                                                const Rigid3d& cam2_from_world,
                                                const Eigen::Vector2d& x1,
                                                const Eigen::Vector2d& x2);

// Angle between the two viewing rays of `point_in_world` from the camera centres, degrees.
double ParallaxDeg(const Rigid3d& cam1_from_world,
                   const Rigid3d& cam2_from_world,
                   const Eigen::Vector3d& point_in_world);

// Squared reprojection error (normalised units) of `point_in_world` seen at `x`; +inf if the point
// is not in front of the camera (depth <= 1e-6 of the distance).
double SquaredReprojectionError(const Rigid3d& cam_from_world,
                                const Eigen::Vector3d& point_in_world,
                                const Eigen::Vector2d& x);

}  // namespace epiloc
