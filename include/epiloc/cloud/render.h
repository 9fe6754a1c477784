// Rendering a point cloud into a pinhole camera: the virtual views the anchoring step matches
// camera frames against (Kurobe et al., "Generate images from LiDAR point cloud": project the
// points with P = K [R | t], the point closer to the camera wins a pixel).
//
// Pipeline of RenderCloud:
//  1. Projection. Points are projected with the camera's pinhole model (distortion is ignored:
//     render into the undistorted camera, Undistorter::undistorted_camera()). A point is culled
//     if its depth z (camera frame, metres) lies outside [near_m, far_m] or its rounded pixel
//     round(u), round(v) lies outside the image; the parts of splats of culled points that would
//     reach into the image are not drawn.
//  2. Splatting and z-buffer. A drawn point at depth z covers a square of side
//     s = the odd number nearest splat_size_m * fx / z, within [1, max_splat_px] (max_splat_px
//     once the size reaches it), pixels: columns [round(u) - s/2, round(u) - s/2 + s) (integer
//     division; rows likewise) with constant depth z. Odd sides keep the splat centred on the
//     point's pixel (an even one would shift the rendering by half a pixel). Each pixel keeps the nearest point; equal depths go to the lower point index, so
//     the result is the same for any number of threads.
//  3. Hole filling (hole_fill_iterations passes). For a pixel of depth d (infinite where empty),
//     walk each of the 8 directions (4 axes: horizontal, vertical, two diagonals) up to
//     hole_fill_radius_px pixels for the first covered pixel nearer than d / (1 +
//     see_through_ratio) (any covered pixel for an empty one). The pixel is enclosed if such pixels
//     exist on both sides of at least 2 of the 4 axes: an empty pixel enclosed is a hole, a covered
//     one is background seen through a gap between nearer splats. Both are replaced by the
//     enclosing surface: inverse depth and attribute interpolated along each enclosing axis,
//     averaged over the axes (weight 1 / span). Inverse depth is linear along an image line on a
//     plane, so a plane is never nearer on both sides of a pixel of itself: covered planar surfaces
//     are never replaced, and outside a convex silhouette no axis has both sides, so silhouettes do
//     not grow. Holes up to 2 * hole_fill_radius_px + 1 pixels across are filled per pass. Filled
//     pixels keep point_index -1.
//  4. Shading: intensity as grey (histogram-equalised over the covered pixels by default, so a
//     rendering has the contrast of a camera image for AKAZE), colour as BGR, or log depth as
//     grey (near bright). Empty pixels are black.
//
// Cost (tools/bench_render.cc, 10 M points, 1242x375 view): ~30 ms on 2 threads, ~40 ms on 1;
// the points are streamed once, everything after the projection scales with the image size.
#pragma once

#include <cstdint>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/cloud/point_cloud.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

enum class RenderShading {
  kAuto,       // colour if the cloud has colour, else intensity, else depth shading
  kIntensity,  // LiDAR intensity as grey (needs intensity)
  kColour,     // the points' colours (needs rgb)
  kDepth,      // log depth as grey, near_m bright, far_m dark (needs nothing)
};
const char* RenderShadingName(RenderShading shading);

struct CloudRenderOptions {
  RenderShading shading = RenderShading::kAuto;
  double near_m = 0.5;             // points closer than this along the optical axis are culled
  double far_m = 120.0;            // points farther than this are culled
  double splat_size_m = 0.08;      // metric side of a splat (about the map's point spacing)
  int max_splat_px = 9;            // largest splat side, pixels, in [1, 64]
  int hole_fill_iterations = 2;    // passes of the hole-filling filter (0 = off)
  int hole_fill_radius_px = 4;     // how far a pass looks for the enclosing surface, [1, 32] px
  double see_through_ratio = 0.1;  // enclosed by pixels nearer by this fraction = see-through
  bool intensity_equalize = true;  // histogram-equalise the intensity over the covered pixels
  int num_threads = 2;             // worker threads (the result does not depend on it)

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct CloudRenderResult {
  cv::Mat image;        // CV_8UC1 (intensity/depth shading) or CV_8UC3 BGR (colour); camera size
  cv::Mat depth;        // CV_32F, z in the camera frame (metres) of the surface seen; 0 = empty
  cv::Mat point_index;  // CV_32S, index of the point seen at the pixel (the point whose splat
                        // covers it), -1 where empty or filled by hole filling
  RenderShading shading = RenderShading::kAuto;  // the shading used (never kAuto)
  int64_t points_drawn = 0;                      // points that passed culling
  int64_t pixels_filled = 0;  // pixels hole filling covered (holes) or replaced (see-through)
};

// Renders `cloud` (in the world frame) into `camera` at cam_from_world (x_cam = R * x_world + t).
// The camera's distortion is ignored. The cloud may hold at most 2^31 - 1 points. Throws Error
// for an invalid camera or options, attribute arrays whose size is not 0 or cloud.size(), or a
// shading the cloud cannot provide. The result is identical for any options.num_threads.
CloudRenderResult RenderCloud(const PointCloud& cloud,
                              const Camera& camera,
                              const Rigid3d& cam_from_world,
                              const CloudRenderOptions& options = CloudRenderOptions());

// The 3-D point (world frame, metres) behind pixel (u, v) (pixel-centre convention: (0, 0) is
// the centre of the top-left pixel) of a rendering: the ray through (u, v) of the pinhole model
// at the depth of the nearest pixel, lifted by cam_from_world.Inverse(). At a splat centre
// (u, v) = round(projection) the point's own depth is used, so a point lying on the ray through
// its pixel centre comes back exactly (to float precision). Returns false where (u, v) is
// outside the image or the depth is empty. Throws Error if `render` does not hold a CV_32F depth
// image of the camera's size.
bool LiftPixel(const CloudRenderResult& render,
               const Camera& camera,
               const Rigid3d& cam_from_world,
               double u,
               double v,
               Eigen::Vector3d* point_in_world);

// A picture of a depth image (CV_32F metres, 0 = empty) for inspection: inverse depth between
// near_m and far_m through the turbo colour map (near red, far blue), empty pixels black.
// Returns CV_8UC3 BGR. Throws Error for another image type or 0 < near_m < far_m violated.
cv::Mat ColouriseDepth(const cv::Mat& depth, double near_m = 1.0, double far_m = 80.0);

}  // namespace epiloc
