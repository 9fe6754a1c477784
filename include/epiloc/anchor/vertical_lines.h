// The world's vertical in a camera's axes from the image's near-vertical line segments (building
// edges, window frames, poles): their vanishing direction. Each segment's two ends, undistorted,
// span an interpretation plane through the camera centre; a vertical 3-D line's plane contains
// the vertical, so the vertical is the direction most nearly in every such plane. It fixes the
// camera's roll against gravity without any 3-D structure, which the map bundle cannot tell well
// from the sightings and the map's planes alone (README, "Where the map bundle's tilt ..."); its
// pitch less well: in a camera looking along the road vertical lines are nearly parallel, and
// only their convergence shows the pitch.
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"

namespace epiloc {

struct VerticalLinesOptions {
  double min_length_px = 25.0;       // shorter segments are ignored (their planes are poorly fixed)
  double max_image_tilt_deg = 25.0;  // only segments within this of the image's vertical
  // The camera's up is taken within this of its -y axis (a vehicle's camera is mounted upright).
  double max_from_upright_deg = 10.0;
  double inlier_deg = 0.3;  // a segment's plane within this of the direction is an inlier
  int ransac_iterations = 300;
  int min_segments = 8;  // fewer inliers: no measurement
  // Added to each axis' standard error, degrees: what the segments' scatter cannot show (a
  // facade or a pole a little off the vertical, an edge that is not one).
  double floor_deg = 0.03;
  uint64_t seed = 1;

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct VerticalDirection {
  Eigen::Vector3d up_in_cam = -Eigen::Vector3d::UnitY();  // unit; the world's up, camera axes
  // Two unit directions orthogonal to up_in_cam (about the camera's x, then z axis) and the
  // covariance of the up's small turn along them, radians^2 (the floor included).
  Eigen::Vector3d tangent_x = Eigen::Vector3d::UnitX(), tangent_z = Eigen::Vector3d::UnitZ();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  int segments = 0;  // inliers used
};

// The vertical seen by `camera` in the 8-bit grey image `grey` (its size must be the camera's),
// or none where fewer than min_segments near-vertical segments agree. Throws Error for an image
// of another size or type.
std::optional<VerticalDirection> MeasureVertical(const cv::Mat& grey,
                                                 const Camera& camera,
                                                 const VerticalLinesOptions& options = {});

}  // namespace epiloc
