// The epipolar image distance of Kyutoku et al. ("Epipolar geometry-based ego-localization using
// an in-vehicle monocular camera"): for an input (query) frame and a database frame of the same
// road with near-parallel optical axes, the epipole's horizontal offset from the principal point
// of the query image is |e_x| = f |q_x| / |q_z| (eq. 1), where q is the database camera centre in
// the query camera frame, so d = 1 / |e_x| = |q_z| / (f |q_x|) grows linearly with the
// along-road distance between the cameras (eq. 2).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/camera/camera.h"

namespace epiloc {

struct EpipoleOptions {
  enum class Model {
    kEssential,    // calibrated: 5-point essential matrix on normalised coordinates (default)
    kFundamental,  // the paper's: 8-point fundamental matrix on pixels; the sign of q_z still
                   // comes from the essential matrix K_db^T F K_query
  };
  Model model = Model::kEssential;
  enum class Robust {
    kFast,    // OpenCV USAC_FAST: LO-RANSAC with a cheap local optimisation (default: the
              // inliers are re-fitted below anyway; ~40 % less time than MAGSAC++ per pair)
    kMagsac,  // OpenCV USAC_MAGSAC: MAGSAC++ (marginalised over the noise scale)
  };
  Robust robust = Robust::kFast;
  // RANSAC inlier threshold, pixels of the query image.
  double max_error_px = 1.0;
  // RANSAC confidence.
  double confidence = 0.999;
  // RANSAC iteration limit (fewer when few matches: RansacIterationCap). The essential matrix
  // with Robust::kFast never draws more than 1000 (OpenCV 4.6's limit for it).
  int max_iterations = 2000;
  // A pair with fewer matches or inliers is marked missing.
  int min_inliers = 20;
  // ... or with a smaller share of inliers among the matches.
  double min_inlier_ratio = 0.2;
  // Median rotation-compensated angle between matched rays below this: the translation is not
  // observable (near-pure rotation or a tiny baseline against the scene depth), pair missing.
  double min_parallax_deg = 0.05;

  void Check() const;
};

struct EpipoleResult {
  bool valid = false;
  std::string failure;  // why not valid: "too few matches", "too few inliers", "no parallax", ...
  int num_matches = 0;
  int num_inliers = 0;
  std::vector<char> inlier_mask;  // per input match
  // Unit direction of the database camera centre in the query camera frame (x right, y down,
  // z forward), sign fixed by cheirality: z > 0 means the database camera is ahead.
  Eigen::Vector3d db_center_in_query = Eigen::Vector3d::Zero();
  // Rotation taking query-camera vectors into the database camera frame.
  Eigen::Matrix3d db_from_query = Eigen::Matrix3d::Identity();
  // Horizontal epipole offset from the principal point, pixels (inf when q_z = 0).
  double e_x_px = 0.0;
  // d = 1/|e_x| = |q_z| / (f |q_x|), 1/pixels; 0 when the cameras are level along the road.
  double distance = 0.0;
  // d with the sign of q_z: positive when the database camera is ahead of the query camera.
  double signed_distance = 0.0;
  double median_parallax_deg = 0.0;
};

// RANSAC iterations for `num_matches` matches: enough to draw one all-inlier sample, with
// options.confidence, from a pair at the smallest inlier share that would be accepted
// (max(min_inlier_ratio, min_inliers / num_matches)); at most options.max_iterations.
int RansacIterationCap(const EpipoleOptions& options, int num_matches);

// Estimates the epipole of the database camera in the query image from matched pixels of two
// undistorted pinhole images (query_pixels[i] <-> db_pixels[i]). Expected failure (too few
// inliers, no parallax) is a result with valid = false, not an exception.
EpipoleResult EstimateEpipole(const std::vector<Eigen::Vector2d>& query_pixels,
                              const Camera& query_camera,
                              const std::vector<Eigen::Vector2d>& db_pixels,
                              const Camera& db_camera,
                              const EpipoleOptions& options);

// The exact d for known camera geometry (tests, synthetic checks): `db_center_in_query` is the
// database camera centre in the query camera frame, `focal_px` the query camera's fx.
double EpipolarDistance(const Eigen::Vector3d& db_center_in_query, double focal_px);

}  // namespace epiloc
