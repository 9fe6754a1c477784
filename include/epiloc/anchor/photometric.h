// Direct (photometric) pose refinement of a camera frame against the rendered map: the final,
// dense step of anchoring, after feature matching and PnP have brought the pose within a few
// decimetres and degrees.
//
// The map is rendered at the current pose (render.h) into a pyramid level of the undistorted
// camera; its pixels with depth, away from depth edges and with a strong intensity gradient are
// lifted to 3-D. The pose change dT (6-DoF) and an affine brightness change (a, b) are then found
// by Gauss-Newton with Huber weights on the residuals
//     r_p = I(pi(dT * x_p)) - (a * R(p) + b),
// I the frame (bilinear, at the same level), R the rendering, x_p the lifted point in the
// rendering camera: dense image alignment as in direct visual odometry (Kerl et al., DVO), with
// the rendering as the key frame. Levels run coarse to fine (a wide basin, then precision); the
// map is re-rendered at the new pose before every level and round, so occlusions and splat
// sizes follow the pose. Unlike features, every textured pixel of the sparse, blurred rendering
// contributes, which is what gives centimetre-level poses in LiDAR maps whose renderings carry
// little fine detail.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/cloud/point_cloud.h"
#include "epiloc/cloud/render.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

struct PhotometricOptions {
  int coarsest_level = 3;        // first pyramid level (image size / 2^level)
  int finest_level = 1;          // last level (0 = full resolution)
  int rounds = 2;                // passes over the levels, re-rendering in between
  int max_iterations = 25;       // Gauss-Newton iterations per level
  int max_pixels = 12000;        // pixels used per level (strongest gradients first)
  double min_gradient = 6.0;     // rendering gradient a pixel needs, grey levels per pixel
  double huber_grey = 12.0;      // Huber threshold of the residuals, grey levels
  double max_depth_step = 0.05;  // pixels whose 3x3 depths spread more (relative) are edges
  double converged_step = 1e-5;  // stop a level when the update is below this (rad, m / depth)
  double min_ncc = 0.3;          // final normalised cross-correlation below this: failure

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct PhotometricResult {
  bool success = false;
  Rigid3d cam_from_world;  // refined pose (the initial one when no step was taken)
  double ncc = 0.0;        // normalised cross-correlation of frame and rendering at the end
  int num_pixels = 0;      // pixels used at the finest level
  int iterations = 0;      // Gauss-Newton iterations over all levels and rounds
  std::string message;     // why it failed ("" on success)
};

// Refines cam_from_world (x_cam = R * x_world + t) of the undistorted grey frame `frame` (CV_8UC1,
// camera size) against `map` (world frame) rendered with `render_options` (its num_threads is
// used as is).
PhotometricResult RefinePhotometric(const cv::Mat& frame,
                                    const Camera& camera,
                                    const PointCloud& map,
                                    const Rigid3d& cam_from_world,
                                    const CloudRenderOptions& render_options,
                                    const PhotometricOptions& options = PhotometricOptions());

}  // namespace epiloc
