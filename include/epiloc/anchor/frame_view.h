// A camera frame beside the map rendered at its pose (`epiloc render`): for checking a map, its
// frame and a pose by eye, and for the README.
#pragma once

#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "epiloc/anchor/map_photos.h"
#include "epiloc/anchor/pose_prior.h"
#include "epiloc/camera/camera.h"
#include "epiloc/cloud/render.h"
#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

enum class ViewPose {
  kAuto,   // the ground truth if the drive has it at the frame time, else the GNSS prior
  kTruth,  // the ground-truth camera pose (needs orientation)
  kGnss,   // the GNSS prior (pose_prior.h: track heading, height from the map's ground)
};
// "auto", "truth", "gnss"; ParseViewPose throws Error for another name.
ViewPose ParseViewPose(const std::string& name);

struct FrameViewInputs {
  std::string cloud_path;         // a point-cloud file or tile directory
  Geodetic map_origin;            // its ENU origin
  std::string drive_dir;
  frame_t frame = kInvalidFrame;  // the drive's frame number
  std::optional<Rigid3d> map_from_cam;  // an explicit pose (map frame); else `pose`
  ViewPose pose = ViewPose::kAuto;
  PriorOptions prior;             // for ViewPose::kGnss
  CloudRenderOptions render;
  std::string photos_dir;         // map photographs that texture the view ("" = none)
  MapPhotoOptions photos;
  double load_radius_m = 90.0;    // map loaded around the camera, metres
  double max_map_distance_m = 1000.0;  // the cloud must come this close to the drive

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct FrameView {
  cv::Mat frame;            // the frame, undistorted, as stored (grey or BGR)
  CloudRenderResult render;  // the map rendered into the undistorted camera
  Camera camera;            // the undistorted camera
  Rigid3d map_from_cam;     // the pose rendered at
  std::string pose_source;  // "given", "ground truth", "GNSS prior"
};

// Renders the map at a frame's pose. Throws Error naming the file for an unreadable cloud or
// image, a frame not in the drive, a cloud far from the drive (another frame), a pose source the
// drive lacks, and a view in which no point of the cloud lies ("does not cover").
FrameView RenderFrameView(const FrameViewInputs& inputs);

// The depth buffer as a 16-bit PNG: value = depth in metres * 256 (KITTI depth convention),
// 0 = no point; depths beyond 255.99 m saturate. Throws Error if the file cannot be written.
void WriteDepthPng(const cv::Mat& depth, const std::string& path);

// The frame above its rendering (both BGR), for comparison by eye.
cv::Mat StackFrameAndRendering(const cv::Mat& frame, const cv::Mat& rendering);

}  // namespace epiloc
