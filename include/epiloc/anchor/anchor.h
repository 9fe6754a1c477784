// LiDAR map anchoring (`epiloc anchor`): an absolute, metric 6-DoF camera pose in a point-cloud
// map from a camera frame and a cheap GPS prior (Kurobe et al., "Matching the Rendered LiDAR
// Point Cloud and Drive Recorder Images").
//
// Per frame:
//  1. The prior (pose_prior.h): GNSS position, track heading, height from the map's ground.
//  2. Candidate poses around it (GenerateCandidates). Each is rendered (render.h) into the
//     frame's undistorted camera; features of the undistorted frame are matched to those of the
//     rendering (image_matching.h: AKAZE, ratio test, RANSAC F); matched rendered pixels are
//     lifted to 3-D through the depth buffer (LiftPixel; pixels at depth discontinuities are
//     skipped); PnP RANSAC + LM (absolute_pose.h) gives a pose. The candidate with the most
//     inliers (then the lowest RMSE) wins.
//  3. Refinement: the map is rendered again at the solved pose and matched with guided search
//     (features near their own position), PnP again, up to refine_rounds times or until the pose
//     moves less than converged_m / converged_deg. Rendering at (nearly) the true pose makes the
//     rendering look like the frame, so matches become many and precise and the depth errors of
//     the splats fall along the viewing rays, where they do not move the pose: this iteration is
//     what gives centimetre accuracy.
//  4. Optionally (photometric = true), direct photometric refinement of that pose (photometric.h);
//     its result replaces the PnP pose only if it succeeds and stays within max_photometric_shift_m.
//  5. Reliability: the pose is `ok` only with at least min_inliers inliers, an RMSE of at most
//     max_rmse_px, within max_prior_sigmas * gnss_sigma_m (horizontally) of the GNSS prior, at a
//     plausible height above the map's ground and nearly level; otherwise `rejected` with the
//     reason. Frames the map does not cover, or without GNSS, get their own status.
// Frames: map = the cloud's local ENU (x east, y north, z up, metres) about the map origin; the
// reported orientation enu_from_cam is in the local ENU at the solved position, as in the result
// CSV (eval/result.h).
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "epiloc/geometry/absolute_pose.h"
#include "epiloc/anchor/image_matching.h"
#include "epiloc/anchor/map_photos.h"
#include "epiloc/anchor/photometric.h"
#include "epiloc/anchor/pose_prior.h"
#include "epiloc/cloud/point_cloud.h"
#include "epiloc/cloud/render.h"
#include "epiloc/core/progress.h"
#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

enum class AnchorStatus {
  kOk,          // a reliable pose
  kRejected,    // a pose was solved but failed the reliability checks (message says which)
  kLost,        // no pose: too few matches or PnP inliers
  kNoCoverage,  // the map has (almost) no points in the view around the prior
  kNoPrior,     // no GNSS position or heading at the frame time
};
// "ok", "rejected", "lost", "no_coverage", "no_prior".
std::string AnchorStatusName(AnchorStatus status);

// The inverse of RenderShadingName (render.h): "auto", "intensity", "colour" (also "color"),
// "depth"; throws Error for another name.
RenderShading ParseRenderShading(const std::string& name);

struct AnchorOptions {
  PriorOptions prior;            // the GPS prior
  CandidateOptions candidates;   // poses rendered around it
  ImageMatchOptions matching;    // frame-to-rendering matching
  // PnP RANSAC + LM. A wide inlier threshold (4 px): points lifted from a LiDAR map carry its
  // range noise and the camera-LiDAR calibration error, 1-3 px at street distances; a strict
  // threshold keeps an arbitrary subset of them and the pose flips between neighbouring
  // solutions (KITTI: max error 0.26-0.40 m at 2 px, 0.27-0.32 m at 4 px over seeds and photo
  // counts).
  PnpOptions pnp = WidePnp();
  CloudRenderOptions render;     // rendering (shading: auto / intensity / colour)
  int refine_rounds = 3;            // re-renders at the solved pose (0 = none)
  bool photometric = false;         // finish with direct photometric refinement (photometric.h)
  PhotometricOptions photometric_options;
  double refine_splat_size_m = 0.03;  // splat size of the refinement renderings (at most the
                                      // first one's): the nearest splat wins a pixel, so large
                                      // splats drag texture on oblique surfaces towards the
                                      // vanishing point (centimetres of along-track bias)
  double guided_radius_px = 12.0;   // refinement rounds match within this radius (0 = anywhere)
  double converged_m = 0.005;       // refinement stops when the pose moves less than this ...
  double converged_deg = 0.02;      // ... and turns less than this
  double load_radius_m = 90.0;      // map tiles loaded around the prior, metres
  double min_coverage = 0.02;       // share of the view a candidate's rendering must fill
  double max_depth_step = 0.05;     // lifted pixels whose 3x3 depths spread more than this
                                    // fraction (plus 0.1 m) are at an edge and skipped
  int lift_radius_px = 3;           // rendered features are lifted onto a plane fitted to the
                                    // map points drawn within this many pixels
  int frame_margin_px = 24;         // frame features farther than this from the rendered area
                                    // are not matched (they cannot have a counterpart)
  int max_frame_features = 5000;    // strongest frame features matched per rendering
  int erode_px = 4;                 // rendered features this close to empty pixels are skipped
  int min_inliers = 40;             // reliability: PnP inliers at least
  double max_rmse_px = 2.5;         // reliability: reprojection RMSE at most, pixels
  double gnss_sigma_m = 3.0;        // horizontal GNSS standard deviation, metres
  double max_prior_sigmas = 4.0;    // reliability: horizontal offset from the prior at most
                                    // this many gnss_sigma_m
  double max_height_offset_m = 1.0;  // reliability: |height above ground - camera_height_m|
  double max_tilt_deg = 15.0;        // reliability: |pitch| and |roll| of the camera at most
  double max_photometric_shift_m = 0.5;  // photometric steps moving the camera more are refused
  double heading_error_deg = 0.0;   // testing: perturb the prior heading uniformly in +-this
  uint64_t seed = 1;                // seeds the heading perturbation and random candidates
  int num_threads = 2;              // frames anchored in parallel

  // Throws Error naming the first invalid field.
  void Check() const;
  static PnpOptions WidePnp();
};

struct AnchorResult {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  AnchorStatus status = AnchorStatus::kLost;
  std::string message;                    // why it is not ok ("" when ok)
  bool has_prior = false;
  PosePrior prior;                        // the (perturbed) prior used
  bool has_pose = false;                  // a pose was solved (ok or rejected)
  Rigid3d map_from_cam;                   // the solved pose, map frame
  Geodetic position;                      // its camera centre, WGS-84
  Eigen::Quaterniond enu_from_cam = Eigen::Quaterniond::Identity();  // local ENU at position
  int num_frame_features = 0;
  int num_matches = 0;                    // of the final round, after the F test
  int num_inliers = 0;                    // PnP inliers of the final round
  double rmse_px = 0.0;                   // their reprojection RMSE
  double coverage = 0.0;                  // share of the view the final rendering fills
  double photometric_ncc = NAN;           // correlation after photometric refinement (if run)
  double photometric_shift_m = NAN;       // how far photometric refinement moved the camera
  int best_candidate = -1;                // index of the winning candidate
  int rounds = 0;                         // refinement rounds run
  double prior_offset_m = 0.0;            // horizontal distance pose - prior, metres
  double height_above_ground_m = NAN;     // camera height above the map's ground at the pose
  double seconds = 0.0;                   // wall-clock time of the frame
  // Anchoring from structure (structure_anchor.h) only; NaN / 0 otherwise.
  double scale_m_per_unit = NAN;          // the similarity's scale (metres per VO unit)
  double seed_scale_m_per_unit = NAN;     // the GPS seed's
  double inlier_share = NAN;              // share of the structure points within the finest
                                          // correspondence distance (num_inliers of them)
  double residual_m = NAN;                // their RMS distance to the map's surface
  double along_information = NAN;         // mean (normal . road direction)^2 of the inliers
  double along_sigma_m = NAN;             // translation sigma along the road: the Hessian's, or
                                          // half the stretch the along-track profile does not
                                          // tell apart (structure_registration.h), if larger
  int structure_points = 0;               // VO points registered
  double scale_drift_per_m = NAN;         // the VO's scale drift estimated over the window:
                                          // relative change of scale per metre of road
  double consensus_move_m = NAN;          // structure: horizontal move of the camera to its
                                          // ok neighbours' median placement (NaN: not moved)
  double bundle_move_m = NAN;             // structure: horizontal move of an ok anchor's camera
                                          // by the map bundle (NaN: not adjusted)
};

// Anchors one frame. `image`: the frame undistorted into `camera` (grey or BGR); `local_map`: the
// map near the prior (map frame about `map_frame`'s origin); `prior` from MakePosePrior;
// `photos`: the map's photographs (map_photos.h), matched instead of renderings (nullptr = render
// the map). Expected failures are statuses, not exceptions. Thread-safe (no shared state).
AnchorResult AnchorFrame(const cv::Mat& image,
                         const Camera& camera,
                         const PointCloud& local_map,
                         const EnuFrame& map_frame,
                         const PosePrior& prior,
                         const AnchorOptions& options,
                         const MapPhotos* photos = nullptr);

// The prior with its heading turned by `delta_deg` (orientation recomputed).
PosePrior RotatePriorHeading(const PosePrior& prior, double delta_deg);

// Inputs of AnchorDrive.
struct AnchorInputs {
  std::string cloud_path;   // map: a point-cloud file or a tile directory (tiled_cloud.h)
  Geodetic map_origin;      // its ENU origin (map_sidecar.h, ResolveMapOrigin)
  std::string drive_dir;    // the drive whose frames are anchored
  std::vector<frame_t> frames;  // frame numbers to anchor; empty = every `every`-th frame
  int every = 1;                // with frames empty: every n-th frame of the drive
  std::string photos_dir;   // drive of the map's photographs (map_photos.h; "" = none)
  std::string vo_path;      // structure anchoring: the VO trajectory (structure_anchor.h)
  MapPhotoOptions photos;
  std::string tile_dir;     // cache of tiles for a large single-file map ("" = <cloud>.tiles)
  int64_t max_whole_points = 20000000;  // larger single-file maps are tiled (bounded memory)
  double max_map_distance_m = 1000.0;   // the cloud must come this close to the drive's GNSS

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct AnchorDriveResult {
  std::string drive_name;
  std::vector<AnchorResult> frames;  // in drive order
  int64_t num_ok = 0;
  double seconds = 0.0;  // wall-clock time of the whole run
};

// Anchors the selected frames of a drive against a map. Throws Error (naming the file) for a
// cloud that is not readable, a cloud far from every GNSS position of the drive (another frame),
// a frame number not in the drive, or images whose size differs from the calibration. `progress`
// gets (frames done, frames).
AnchorDriveResult AnchorDrive(const AnchorInputs& inputs,
                              const AnchorOptions& options,
                              const ProgressCallback& progress = nullptr);

}  // namespace epiloc
