// Local 3-D structure of a route database: SIFT features matched between neighbouring survey
// frames of a drive, filtered by the epipolar geometry of the frames' known poses, joined into
// tracks and triangulated multi-view (DLT, then Gauss-Newton on the reprojection error with
// outlying observations dropped one at a time), stored in the points3d / observations tables
// (schema version 3, db_schema/0003_points.sql).
//
// Poses are the database's: camera centre `center_in_enu` and rotation `enu_from_cam` (camera
// x right, y down, z forward) of each frame; features are in the drive's undistorted pinhole
// camera. Works the same for positions from RTK ground truth, NDT or a georeferenced VO
// trajectory, as long as they carry the orientation; frames without one are skipped.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "epiloc/camera/camera.h"
#include "epiloc/core/progress.h"
#include "epiloc/feature/matcher.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

class Database;

struct TriangulateOptions {
  // Each frame is matched with up to this many following frames of its drive (tracks chain
  // further: frame i reaches i + 3 through i + 1 or i + 2; KITTI 0005: 2 neighbours give 4.5 %
  // fewer points than 3 in 70 % of the time, with the same 6-DoF refinement accuracy) ...
  int num_neighbours = 2;
  // ... whose camera centre is at least this far away (frames of a stopped vehicle add no
  // parallax, so the search passes over them), metres ...
  double min_baseline_m = 0.2;
  // ... and at most this far away, metres.
  double max_baseline_m = 15.0;
  // Strongest features per frame that take part in matching (0 = all stored).
  int max_features = 0;
  // Lowe's ratio test and FLANN settings of the matcher. 12 checks instead of the matcher's 64:
  // neighbouring frames look alike, so a short search finds nearly the same matches (KITTI
  // 0005: 16 checks give 4 % fewer points than 64 in 40 % of the time; 12 another 2 % fewer).
  MatchOptions matching = DefaultMatching();
  // A match farther than this from its epipolar line (given the known poses), in either image,
  // is rejected, pixels.
  double max_epipolar_error_px = 2.0;
  // Observations with a larger reprojection error are dropped (worst first), pixels.
  double max_reprojection_error_px = 2.0;
  // A point needs two of its rays to meet at least at this angle, degrees. Low on purpose: the
  // far, thin-parallax points (depth uncertain, bearing exact) still fix the rotation and,
  // with many, the along-track position of a frame registered against them; measured on the
  // KITTI drive, 0.75 instead of 1.5 degrees lowers the refinement's along-track error.
  double min_triangulation_angle_deg = 0.75;
  // Depth along every observing camera's optical axis must lie in [min, max], metres.
  double min_depth_m = 0.5;
  double max_depth_m = 150.0;
  // A point needs at least this many observations (>= 2).
  int min_observations = 2;
  // Worker threads for matching and triangulation (0 = one per core).
  int num_threads = 0;

  // Throws Error naming the first invalid field.
  void Check() const;

  static MatchOptions DefaultMatching() {
    MatchOptions matching;
    matching.num_checks = 12;
    return matching;
  }
};

struct TriangulateSummary {
  int64_t num_drives = 0;                  // drives with at least two oriented frames
  int64_t num_frames = 0;                  // oriented frames used
  int64_t frames_without_orientation = 0;  // skipped: no enu_from_cam
  int64_t num_pairs = 0;                   // frame pairs matched
  int64_t num_matches = 0;                 // ratio-test matches over all pairs
  int64_t num_epipolar_inliers = 0;        // matches consistent with the known poses
  int64_t num_tracks = 0;                  // tracks of >= 2 observations in distinct frames
  int64_t num_points = 0;                  // points written
  int64_t num_observations = 0;            // their observations
  double mean_track_length = 0.0;          // observations per point
  double mean_error_px = 0.0;              // mean over points of their RMS reprojection error
  double seconds = 0.0;                    // wall-clock time of the whole step
};

// Replaces the database's points with those triangulated from every drive (ClearPoints, then all
// writes, in one transaction: an error leaves the stored points as they were). `progress` gets
// (frames matched, frames). Throws Error for invalid options or database failures.
TriangulateSummary TriangulateDatabase(Database& db,
                                       const TriangulateOptions& options,
                                       const ProgressCallback& progress = nullptr);

// One observation of a track: a pixel of the undistorted pinhole `camera` in a frame with pose
// cam_from_world (x_cam = R * x_world + t).
struct TrackObservation {
  Rigid3d cam_from_world;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct TrackTriangulation {
  bool valid = false;
  Eigen::Vector3d point_in_world = Eigen::Vector3d::Zero();
  std::vector<char> inlier_mask;  // per observation: kept
  double rms_error_px = 0.0;      // over the kept observations
  double max_angle_deg = 0.0;     // largest angle between two kept rays
};

// Triangulates one track: DLT over all observations, Gauss-Newton on the pixel reprojection
// error, then the worst observation above max_reprojection_error_px dropped and the rest refitted
// until all fit. Valid with >= min_observations kept, a ray angle >= min_triangulation_angle_deg
// and the depth range met in every kept view (an observation behind its camera or outside the
// range counts as an outlier). Solved about the first camera's centre, so world coordinates far
// from the origin (a long drive's ENU) lose no precision.
TrackTriangulation TriangulateTrack(const std::vector<TrackObservation>& observations,
                                    const Camera& camera,
                                    const TriangulateOptions& options);

}  // namespace epiloc
