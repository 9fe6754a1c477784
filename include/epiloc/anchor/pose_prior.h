// The GPS prior of a camera frame in a LiDAR map, and the candidate poses rendered around it
// (Kurobe et al., "Generate Images from Drive Recorder Image": the projection matrix from the GPS
// position and the rough direction of travel, Eq. (1)-(2), with candidates made by perturbing the
// angles).
//
// The prior of a frame at time t:
//  - horizontal position: the GNSS track interpolated at t (PositionTrack::Interpolate);
//  - heading: the direction of the GNSS track at t, from a least-squares quadratic in time fitted
//    per axis (east, north) to the GNSS samples within +-heading_window_s of t (widened up to
//    max_heading_window_s until the samples span min_heading_baseline_m); its derivative at t;
//  - height: the map's ground under the horizontal position (a low percentile of the heights of
//    the map points within ground_radius_m) plus camera_height_m, because consumer GNSS altitude
//    is poor; the GNSS altitude only where the map has no points there;
//  - orientation: a level camera (x right, y down, z forward) looking along the heading.
// Frames: map = the cloud's local ENU (x east, y north, z up, metres); compass heading = degrees
// clockwise from north.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "epiloc/cloud/point_cloud.h"
#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"

namespace epiloc {

struct PriorOptions {
  double camera_height_m = 1.65;       // optical centre above the road, metres (KITTI: 1.65)
  double ground_radius_m = 4.0;        // map points within this horizontal radius find the ground
  double ground_percentile = 10.0;     // ground height = this percentile of their heights
  int min_ground_points = 20;          // fewer points there: no ground (GNSS altitude is used)
  double heading_window_s = 2.0;       // half-width of the track-direction fit, seconds
  double max_heading_window_s = 10.0;  // the window widens up to this half-width ...
  double min_heading_baseline_m = 5.0;  // ... until the samples in it span this distance

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct PosePrior {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  Eigen::Vector3d position_in_map = Eigen::Vector3d::Zero();  // camera centre, metres
  double heading_deg = 0.0;          // compass heading of the camera's optical axis
  bool has_ground = false;           // the height came from the map's ground
  double ground_z_m = 0.0;           // map height of the ground (when has_ground)
  Rigid3d map_from_cam;              // level camera at position_in_map looking along heading_deg
};

// map_from_cam rotation of a camera looking along compass heading `heading_deg`, pitched up by
// `pitch_deg` and rolled clockwise (seen from behind) by `roll_deg`.
Eigen::Matrix3d MapFromCamRotation(double heading_deg, double pitch_deg = 0.0, double roll_deg = 0.0);
// Compass heading (degrees) of a camera's optical axis projected onto the horizontal plane.
double CameraHeadingDeg(const Eigen::Matrix3d& map_from_cam);

// Direction of the GNSS track at `timestamp_s` as a compass heading in the map frame (see the top
// of the file); nullopt when fewer than 3 samples lie in the widest window or they do not span
// min_heading_baseline_m (e.g. the vehicle stands still).
std::optional<double> TrackHeadingDeg(const PositionTrack& gnss,
                                      const EnuFrame& map_frame,
                                      double timestamp_s,
                                      const PriorOptions& options);

// Height of the ground (metres, map frame) under `xy` from `cloud` (see PriorOptions); nullopt
// when fewer than min_ground_points lie within ground_radius_m.
std::optional<double> GroundHeight(const PointCloud& cloud,
                                   const Eigen::Vector2d& xy,
                                   const PriorOptions& options);

// The prior of a frame at `timestamp_s` (see the top of the file); `cloud` = the map near the
// frame. nullopt when the GNSS has no position at that time or no heading can be derived.
std::optional<PosePrior> MakePosePrior(const PositionTrack& gnss,
                                       const EnuFrame& map_frame,
                                       const PointCloud& cloud,
                                       frame_t frame,
                                       double timestamp_s,
                                       double max_gap_s,
                                       const PriorOptions& options);

// Candidate poses around a prior. Candidate 0 is the prior; then a stencil of single
// perturbations at +-the full ranges: yaw, along-track, lateral (in that order, + before -); the
// rest are random: every quantity uniform within +-its range (std::mt19937_64 seeded with
// `seed`). Offsets are in the prior camera's level frame (along = its heading, lateral = to its
// right, height = up).
struct CandidateOptions {
  int num_candidates = 7;         // poses rendered per frame, the prior included (>= 1)
  double yaw_range_deg = 6.0;     // heading perturbation
  double pitch_range_deg = 1.0;   // pitch perturbation (random candidates only)
  double roll_range_deg = 0.5;    // roll perturbation (random candidates only)
  double along_range_m = 4.0;     // along-track offset
  double lateral_range_m = 3.0;   // lateral offset (a consumer GPS is often metres off the lane)
  double height_range_m = 0.2;    // height offset (random candidates only)

  // Throws Error naming the first invalid field.
  void Check() const;
};

// map_from_cam poses of the candidates (see CandidateOptions).
std::vector<Rigid3d> GenerateCandidates(const PosePrior& prior,
                                        const CandidateOptions& options,
                                        uint64_t seed);

}  // namespace epiloc
