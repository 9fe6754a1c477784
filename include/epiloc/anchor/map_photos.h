// Map photographs (`epiloc anchor --map-photos`, `epiloc render --map-photos`): the camera frames
// of the mapping drive, with their poses, used beside the LiDAR map's geometry.
//
// A point-coloured map renders as blocks: one colour per point, one splat per point, so its
// rendering keeps little of the texture feature detectors need (on the KITTI drive, 10-30 correct
// AKAZE matches per frame: anchoring fails). A mobile-mapping survey keeps the photographs the map
// was coloured from. Each one is a rendering of the map at its own pose with perfect texture: the
// map's depth is rendered at the photograph's pose (MapPhotoCache::Photo), its features are lifted
// onto the map through that depth (MapPhotoCache::Features, with the anchor's local-plane lift),
// and a frame matched to it gets 2D-3D correspondences against the LiDAR geometry. This is the
// limit of projective texturing with no parallax: no resampling, no holes, no splat artefacts.
//
// For pictures, Texture colours a rendering at any pose from the photographs (projective
// texturing): each pixel's 3-D point (its ray at the rendered depth) is projected into the
// photographs nearest to the pose (centre distance, optical axes within max_view_angle_deg),
// nearest first; the first one that sees it unoccluded (its depth agrees with that photograph's
// rendered depth within depth_tolerance * z + depth_tolerance_m) gives the grey value, sampled
// bilinearly. Pixels no photograph sees stay 0.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "epiloc/anchor/image_matching.h"
#include "epiloc/camera/camera.h"
#include "epiloc/camera/undistorter.h"
#include "epiloc/cloud/point_cloud.h"
#include "epiloc/cloud/render.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"

namespace epiloc {

struct MapPhotoOptions {
  int max_views = 3;                  // photographs used per pose (refinement, texturing)
  double max_view_distance_m = 20.0;  // photographs taken farther from the pose are unused
  double max_view_angle_deg = 45.0;   // ... and those whose optical axis turns more than this
  double depth_tolerance = 0.05;     // visible: |z - view depth| <= this * z + depth_tolerance_m
  double depth_tolerance_m = 0.15;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// The photographs and their poses in the map frame. Immutable after construction: shared
// by threads.
class MapPhotos {
 public:
  // Loads the drive `drive_dir` (frames and the oriented poses: ground truth, else GNSS). Throws
  // Error naming the drive when it has no camera orientations or no posed frame.
  MapPhotos(const std::string& drive_dir, const EnuFrame& map_frame, const MapPhotoOptions& options);
  MapPhotos(const MapPhotos&) = delete;
  MapPhotos& operator=(const MapPhotos&) = delete;

  const MapPhotoOptions& options() const { return options_; }
  const std::string& drive_dir() const { return drive_.dir; }
  int size() const { return static_cast<int>(poses_.size()); }

  // Indices (0 .. size() - 1) of the usable photographs for a camera at map_from_cam, nearest
  // first, at most options().max_views.
  std::vector<int> Nearest(const Rigid3d& map_from_cam) const;

  // Photograph `index`, undistorted, grey; its pose and (undistorted) camera.
  cv::Mat Read(int index) const;
  const Rigid3d& map_from_photo(int index) const { return poses_[index].map_from_cam; }
  const Camera& camera() const { return undistorter_.undistorted_camera(); }

 private:
  struct Pose {
    size_t frame_index;   // into drive_.frames
    Rigid3d map_from_cam;
  };
  MapPhotoOptions options_;
  Drive drive_;
  Undistorter undistorter_;
  std::unique_ptr<FrameReader> reader_;
  std::vector<Pose> poses_;
};

// A photograph with the map's geometry seen from it.
struct MapPhoto {
  cv::Mat grey;                 // the undistorted photograph
  CloudRenderResult render;     // the local map rendered at the photograph's pose (depth)
  Rigid3d cam_from_map;
  // Features of the photograph that lie on the map (lifted through `render`), and their 3-D
  // points in the map frame: made by MapPhotoCache::Features on first use.
  bool has_features = false;
  ImageFeatures features;
  std::vector<Eigen::Vector3d> points;
};

// Lifts a pixel of a rendering to the map (anchor.cc: a plane fitted to the map points drawn
// around it); false where it cannot be lifted reliably.
using LiftFunction = std::function<bool(const CloudRenderResult& render, const Camera& camera,
                                        const Rigid3d& cam_from_map, const cv::Point2f& pixel,
                                        Eigen::Vector3d* point)>;

// The photographs of one anchored frame, prepared on first use against its local map. Not
// thread-safe: one per frame.
class MapPhotoCache {
 public:
  MapPhotoCache(const MapPhotos& photos,
                  const PointCloud& local_map,
                  const CloudRenderOptions& render_options);

  const MapPhotos& photos() const { return photos_; }

  // Photograph `index` (MapPhotos' numbering) with the map's depth seen from it.
  const MapPhoto& Photo(int index);
  // The same with its features lifted onto the map by `lift`.
  const MapPhoto& Features(int index, const ImageMatchOptions& options, const LiftFunction& lift);

  // Replaces render->image by the photographs' texture seen from cam_from_map (CV_8UC1; 0 where
  // no photograph sees the pixel's point) and returns the mask (CV_8UC1, 255 = textured).
  cv::Mat Texture(const Camera& camera, const Rigid3d& cam_from_map, CloudRenderResult* render);

 private:
  const MapPhotos& photos_;
  const PointCloud& local_map_;
  CloudRenderOptions render_options_;
  std::map<int, MapPhoto> views_;
};

}  // namespace epiloc
