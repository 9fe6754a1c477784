// Exact rendering of the synthetic world into a camera.
//
// Each textured quad is mapped into the undistorted image by the homography texture -> image
// (perspective-correct per pixel). Pixels are covered where the ray through the pixel centre hits
// the quad in front of the near plane (an exact clip, done per pixel in homogeneous coordinates),
// and the nearest quad wins by the exact per-pixel plane depth. Textures are sampled trilinearly
// from mip levels chosen by the per-pixel texture footprint. Lens distortion is applied
// afterwards by remapping with Camera's model, so a world point X always appears at
// camera.Project(cam_from_world * X). Optional: supersampling, motion blur along the per-pixel
// image motion, exposure gain, white balance, Gaussian noise; moving surfaces and sunlight with
// cast shadows (RenderExtras).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/synth/lighting.h"
#include "epiloc/synth/world.h"

namespace epiloc {

struct RenderOptions {
  int supersampling = 1;       // render N x N samples per pixel and average (1 = off)
  bool mipmapping = true;      // anti-aliased texture sampling (trilinear mip levels)
  double near_m = 0.05;        // near plane: surfaces closer than this along z are clipped
  double exposure_gain = 1.0;  // multiplies the image intensities
  double noise_sigma = 0.0;    // Gaussian noise, standard deviation in 8-bit grey levels
  uint64_t noise_seed = 0;     // seed of the noise (use one per frame)
  int max_blur_taps = 7;       // most samples along the motion-blur path of one pixel
  bool depth = false;          // also return the depth image
  bool surface_ids = false;    // also return the surface index image

  // Appearance variants.
  // Per-channel gains (red, green, blue) after exposure_gain: the camera's white balance.
  std::array<double, 3> white_balance_rgb = {1.0, 1.0, 1.0};

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct RenderResult {
  cv::Mat image;       // CV_8UC3, BGR, the camera's size
  cv::Mat depth;       // CV_32F, z in the camera frame (metres); 0 where only sky is seen
  cv::Mat surface_id;  // CV_32S, index into World::surfaces (or RenderExtras); -1 for sky
};

// Optional additions to one rendering (appearance variants). None: the static world, unshaded.
struct RenderExtras {
  // Surfaces posed in the world for this frame (moving cars), drawn with the world's; their
  // `texture` fields index `textures`. In RenderResult::surface_id, (*surfaces)[k] has index
  // world.surfaces.size() + k.
  const std::vector<Surface>* surfaces = nullptr;
  const std::vector<Texture>* textures = nullptr;
  // Sun shading and cast shadows, built for the same world (see lighting.h).
  const Lighting* lighting = nullptr;
};

// Renders one world into one camera. Construction precomputes the distortion maps; Render() is
// const and may run concurrently from several threads. Keeps no reference to the world.
class Renderer {
 public:
  Renderer(const Camera& camera, const RenderOptions& options);

  const Camera& camera() const { return camera_; }
  const RenderOptions& options() const { return options_; }

  // Renders `world` seen from the pose cam_from_world (x_cam = R * x_world + t).
  // `cam_from_world_exposure_end`, when given, is the pose at the end of the exposure: the image
  // is blurred along each pixel's motion, symmetrically about the pose at mid-exposure
  // (cam_from_world), so the sharp geometry stays at the frame's pose. `noise_seed`, when given,
  // replaces options().noise_seed (one seed per frame). `extras` adds moving surfaces and the sun;
  // without them the rendering costs what it always did.
  RenderResult Render(const World& world,
                      const Rigid3d& cam_from_world,
                      const std::optional<Rigid3d>& cam_from_world_exposure_end = std::nullopt,
                      std::optional<uint64_t> noise_seed = std::nullopt,
                      const RenderExtras& extras = RenderExtras()) const;

 private:
  Camera camera_;
  RenderOptions options_;
  Camera pinhole_;       // undistorted camera covering the whole distorted view
  Camera supersampled_;  // pinhole_ scaled by the supersampling factor
  // Normalised image coordinates (x/z, y/z) of each output pixel's ray; CV_64FC2.
  cv::Mat rays_;
  // Remap from the output image into pinhole_ (CV_32F); empty without distortion.
  cv::Mat map_x_, map_y_;
  // Gaussian noise (CV_32FC3) cut at a per-frame offset; empty without noise.
  cv::Mat noise_tile_;
};

// The sky colour (BGR, 0..255 as floats) for a unit view direction in world ENU.
cv::Vec3f SkyColour(const Eigen::Vector3d& direction_in_world);

}  // namespace epiloc
