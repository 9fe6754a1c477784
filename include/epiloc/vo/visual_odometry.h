// Keyframe-based monocular visual odometry (`epiloc vo`): the camera's trajectory in a relative
// frame of unknown scale, for georeferencing with a few absolute anchors (georef/, Kurobe et al.
// use ORB-SLAM for this step).
//
// Pipeline per frame: KLT tracks (klt_tracker.h, search started at the projection of the track's
// 3-D point under a constant-velocity pose prediction), motion-only pose refinement against the
// map points (Ceres, Huber; PnP RANSAC when the prediction fails), keyframe selection, and at
// each keyframe triangulation of new points from the first keyframe that saw them and a local
// bundle adjustment (bundle_adjustment.h) over the last `ba_window` keyframes, the keyframes
// outside the window that see the same points held fixed.
//
// Finish: a global bundle adjustment of each segment's keyframes and points (an offline survey
// can afford it: one solve of the whole map after the last frame).
//
// Initialisation: a reference frame is kept until the median feature displacement reaches
// `init_min_flow_px`; then an essential matrix (two_view.h) gives the second keyframe and the
// first points, the frames in between are posed by PnP. The first segment's world frame is the
// first keyframe's camera frame (x right, y down, z forward), its unit the distance between the
// first two keyframes.
//
// Tracking loss (too few inliers) ends a segment; the odometry re-initialises from the lost frame
// and starts a new segment. Segments are joined into one trajectory: the new segment's first
// keyframe is put at the pose predicted for the lost frame (constant velocity) and its scale is
// set so that the median depth of its points equals that of the last keyframe before the loss.
// The join is an assumption (no shared structure), so each pose carries its segment number;
// georeferencing by piecewise anchoring (georef/) absorbs a wrong join scale between anchors.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/core/progress.h"
#include "epiloc/core/types.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"
#include "epiloc/vo/bundle_adjustment.h"
#include "epiloc/vo/klt_tracker.h"
#include "epiloc/vo/two_view.h"

namespace epiloc {

struct VoOptions {
  KltOptions klt;                  // feature tracking
  TwoViewOptions two_view;         // initialisation (focal_px is set from the camera)
  double init_min_flow_px = 15.0;  // median displacement since the reference before two-view
  int init_max_frames = 40;        // frames after which an unusable reference is replaced
  double max_error_px = 1.5;       // inlier threshold of pose refinement, triangulation and BA
  int min_inliers = 30;            // fewer 2D-3D inliers in a frame = tracking lost
  // A new keyframe when the baseline since the last one reaches this share of the median scene
  // depth,
  double keyframe_baseline_ratio = 0.08;
  // or when the tracked map points fall below this share of those of the last keyframe (and the
  // baseline is at least keyframe_min_baseline_ratio of the depth),
  double keyframe_tracked_ratio = 0.75;
  double keyframe_min_baseline_ratio = 0.02;
  int keyframe_max_interval = 15;  // or after this many frames (if the camera moved at all)
  double min_triangulation_parallax_deg = 1.0;  // a new point needs this ray angle
  int ba_window = 8;                            // keyframes adjusted by the local BA
  int ba_iterations = 8;                        // Levenberg-Marquardt iterations per local BA
  // Iterations of the final BA over all keyframes and points of each segment (Finish); 0: none
  // (then the map forgets what lies behind the local window).
  int global_ba_iterations = 20;
  double huber_px = 2.0;  // robust loss scale of BA and refinement
  // Keep every triangulated point (also those behind the local window) for Result().points, e.g.
  // to register the structure to a LiDAR map (anchor/structure_anchor.h).
  bool keep_points = true;
  int num_threads = 2;    // Ceres threads; frames are read ahead on one more

  // Throws Error naming the first invalid field.
  void Check() const;
};

// What happened to a frame.
enum class VoFrameStatus {
  kInitializing,  // no map yet (waiting for parallax); posed later if the map starts
  kTracked,       // posed against the map
  kKeyframe,      // posed and made a keyframe
  kLost,          // tracking failed: a new segment starts from this frame
};

// The pose of one frame. world_from_cam: x_in_world = R * x_in_cam + t (camera x right, y down,
// z forward); units of the odometry (relative scale).
struct VoFramePose {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  Rigid3d world_from_cam;
  int segment = 0;        // 0, 1, ...: which initialisation the pose belongs to
  bool keyframe = false;  // a bundle-adjusted keyframe (others are tracked frames)
  int inliers = 0;        // 2D-3D inliers of the frame's pose
};

struct VoSegment {
  int id = 0;
  frame_t first_frame = kInvalidFrame;  // first and last posed frame
  frame_t last_frame = kInvalidFrame;
  int64_t num_poses = 0;
  int64_t num_keyframes = 0;
  double join_scale =
      1.0;  // scale applied when joining it to the previous segment (1 for the first)
};

struct VoSummary {
  int64_t frames = 0;  // processed
  int64_t posed = 0;   // with a pose
  int64_t keyframes = 0;
  int64_t lost = 0;                // tracking losses (segments - 1 when every loss re-initialised)
  double mean_inliers = 0.0;       // per posed frame
  double seconds = 0.0;            // wall-clock time of the processing (reading included)
  double ba_seconds = 0.0;         // of it, in local and global bundle adjustment
  double global_ba_seconds = 0.0;  // of that, in the global bundle adjustment (Finish)
  double frames_per_s() const { return seconds > 0.0 ? frames / seconds : 0.0; }
};

// One sighting of a VoPoint: the frame and the point's normalised image coordinates there (x/z,
// y/z of the distortion-free ray).
struct VoObservation {
  frame_t frame = kInvalidFrame;
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();
};

// A triangulated 3-D point of the odometry's map, in the trajectory's world frame and units
// (after the final bundle adjustment and the joins of segments).
struct VoPoint {
  Eigen::Vector3d point_in_world = Eigen::Vector3d::Zero();
  int segment = 0;
  frame_t first_frame = kInvalidFrame;  // first and last keyframe that observed it
  frame_t last_frame = kInvalidFrame;
  int observations = 0;                 // keyframes that observed it
  double parallax_deg = 0.0;            // angle between the rays from the first and the last of
                                        // them (a small angle: an uncertain depth)
  // Its sightings, where the structure keeps them (the anchors' SIFT structure,
  // anchor/structure_sift.h); empty otherwise (the odometry's own points, files).
  std::vector<VoObservation> seen;
};

// VoPoint::parallax_deg of a point seen from two camera centres: the angle between the rays,
// degrees.
double ParallaxDeg(const Eigen::Vector3d& point,
                   const Eigen::Vector3d& first_centre,
                   const Eigen::Vector3d& last_centre);

struct VoResult {
  std::vector<VoFramePose> poses;  // posed frames in time order
  std::vector<VoPoint> points;     // map points (VoOptions::keep_points), by first_frame
  std::vector<VoSegment> segments;
  VoSummary summary;
};

// Frame-by-frame odometry. Frames must come in time order from one camera.
class VisualOdometry {
 public:
  VisualOdometry(const Camera& camera, const VoOptions& options);
  ~VisualOdometry();
  VisualOdometry(const VisualOdometry&) = delete;
  VisualOdometry& operator=(const VisualOdometry&) = delete;

  // Processes a frame: CV_8UC1 (or BGR, converted) of the camera's size, distorted as the camera
  // model says. Throws Error for a wrong image size or type.
  VoFrameStatus ProcessFrame(frame_t frame, double timestamp_s, const cv::Mat& image);

  // Ends the odometry (no more frames): a bundle adjustment of every keyframe and point of each
  // segment (VoOptions::global_ba_iterations), the segment's first keyframe and scale held. Each
  // segment is adjusted on its own; its join to the previous one stays where tracking put it.
  void Finish();

  // The trajectory so far: non-keyframes are expressed relative to their reference keyframe, so
  // they follow the keyframes' final (bundle-adjusted) poses.
  VoResult Result() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

// Runs the odometry over every frame of `drive` (reading the next frame ahead on another thread),
// then Finish().
// `progress` gets (frames done, frames total). Throws Error for unreadable frames.
VoResult RunVisualOdometry(const Drive& drive,
                           const VoOptions& options,
                           const ProgressCallback& progress = nullptr);

// Writes the poses as a TUM trajectory (io/pose_files.h): "t x y z qx qy qz qw" of world_from_cam
// per posed frame, one file for all segments; '#' comment lines name the drive and list each
// segment ("segment K frames A..B poses N keyframes M join_scale S") and, with `drive_dir`, the
// drive ("drive_dir <absolute path>", which `epiloc georef` maps the times to frame numbers of).
void WriteVoTrajectory(const VoResult& result,
                       const std::string& path,
                       const std::string& drive_name = "",
                       const std::string& drive_dir = "");

// The points file beside a trajectory file: its extension replaced by ".points.csv"
// ("vo.tum" -> "vo.points.csv").
std::string VoPointsPath(const std::string& trajectory_path);

// Writes the map points as CSV: x,y,z (world frame of the trajectory, its units), segment,
// first_frame, last_frame, observations, parallax_deg. Throws Error on I/O failure.
void WriteVoPoints(const std::vector<VoPoint>& points, const std::string& path);

// Reads a file WriteVoPoints wrote (parallax_deg optional: NaN without). Throws Error
// "<path>:<line>: ..." for a malformed row.
std::vector<VoPoint> ReadVoPoints(const std::string& path);

}  // namespace epiloc
