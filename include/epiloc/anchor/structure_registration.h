// Registration of a monocular reconstruction's 3-D points to a LiDAR map with a similarity
// transform (Sim(3): scale, rotation, translation): robust point-to-plane ICP with scale, in the
// spirit of Caselitz et al., "Monocular camera localization in 3D LiDAR maps" (IROS 2016).
//
// Given points p_i (the VO's world frame, its units) and an initial map_from_world similarity
// S = (s, R, t) (x_in_map = s * R * p + t), each iteration pairs every transformed point with its
// nearest map point q_i (an exact kd-tree over the map, FLANN) within the current correspondence
// distance and measures the distance to the map's local surface there, from a PCA of the map
// points around q_i (computed once per map point used): to its plane where the neighbourhood is
// planar (facades, road, car bodies), to its line where it is linear (poles, edges, kerbs), else
// to q_i itself. It minimises sum rho(|P_i (S p_i - q_i)|) (P_i the projector of that distance)
// over a Sim(3) update by Gauss-Newton with iteratively reweighted least squares (rho = Huber,
// then Tukey at fine levels; scale proportional to the correspondence distance). The correspondence
// distance goes from coarse to fine (`max_distances_m`), so a seed metres off converges and the
// final fit only uses points close to the surface. Levels coarser than `min_scale_distance_m` keep
// the scale: nearest-neighbour pairs of a shrunken structure are always close, so a free scale at
// coarse levels collapses the structure. Before the ICP, a search over translations (along and
// across `direction`, within
// +-search_along_m / +-search_lateral_m) and headings (+-search_yaw_deg) about the seed scores a
// subsample of the points by how many fall in occupied cells of the map and starts the ICP from the
// best (ICP alone converges only within about half the size of the structure's features: a GPS seed
// 3 m along a street of windows can lock onto the next window). Reliability: the share of points
// within the finest distance (inliers), their RMS distance to the plane, the scale relative to the
// seed's, and the conditioning of the problem along a given direction (the road): the information
// the inliers' normals carry along it, and the standard deviation of the translation along it from
// the Gauss-Newton Hessian or, where larger, from the profile of points on the map's surface
// over moves along it (a street of facades is not fixed along the road by its structure).
// Monocular scale drift (optional, ScaleDriftPath): a VO's scale changes along its path (the
// shared KITTI drive's by about 0.3 % per metre), so one similarity fits a window's structure at
// its middle and tilts and shifts the camera at its end (exact structure with 5 % drift over 40 m,
// camera 12 m behind its middle: 0.5 deg, 0.12 m). With a drift model the structure is first
// warped, p -> p + kappa * a(p) (linear in kappa, below), and kappa is estimated with the scale.
// Frames: map = the cloud's frame (metres); world = the reconstruction's frame (its units).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "epiloc/cloud/point_cloud.h"

namespace epiloc {

// x_in_b = scale * rotation * x_in_a + translation.
struct Similarity3 {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x_in_a) const {
    return scale * (rotation * x_in_a) + translation;
  }
  Similarity3 Inverse() const;
};

struct StructureRegistrationOptions {
  // Correspondence distances from coarse to fine, metres (a pair farther apart is ignored).
  std::vector<double> max_distances_m = {4.0, 2.0, 1.0, 0.5, 0.3};
  int max_iterations_per_level = 8;  // Gauss-Newton iterations per level at most ...
  double converged_m = 2e-3;         // ... until no point moves more than this (about)
  // Levels with a distance at most this use Tukey's loss, coarser ones Huber's. Monocular
  // structure holds many points off the map's surfaces (above the LiDAR's field of view, far,
  // moving): Tukey ignores them and ends nearer the truth on KITTI; but a Tukey level cannot
  // correct a scale error larger than its scale at the structure's ends, so Huber comes first.
  double tukey_max_distance_m = 0.6;
  double loss_scale_ratio = 0.3;      // the robust loss's scale = this * the level's distance
  int normal_neighbours = 12;         // map points in a normal's PCA
  double normal_radius_m = 0.6;       // of which at most this far from the paired map point
  double max_planarity = 0.25;        // plane where smallest / middle PCA eigenvalue <= this, else
  double max_linearity = 0.5;         // line where middle / largest <= this, else point
  double min_scale_distance_m = 1.2;  // levels with a larger distance hold the scale
  double search_along_m = 8.0;        // seed search: translations along the direction within +-this
  double search_lateral_m = 8.0;      // ... across it (horizontally) within +-this
  double search_step_m = 0.5;         // ... in steps of this (0: no search)
  double search_yaw_deg = 6.0;        // ... headings within +-this
  double search_yaw_step_deg = 1.5;   // ... in steps of this
  int search_points = 400;            // ... scoring this many points (evenly subsampled)
  double search_truncation_m = 0.5;   // ... by the share of them in map cells of half this side
  // ... and the cells this far above and below each map point's (rounded up to whole cells): the
  // search moves the seed horizontally only, and its height (the ground beneath the GNSS plus a
  // nominal camera height) is off by decimetres (another vehicle's mount; on a grade, the ground
  // percentile's bias). On a grade, cells of exact height would let the road's ground points
  // trade such a height error for an along-road move (1 cm for 0.6 m on a 1 degree road).
  double search_height_m = 0.25;
  // Scale drift (StructureDrift::estimate): estimated at the levels that free the scale, at most
  // this relative change of scale per metre of road (0.005: 20 % over a 40 m window, beyond any
  // usable monocular VO).
  double max_scale_drift_per_m = 0.005;
  // The along-road profile (along_ambiguity_m) also finds moves that put significantly more
  // points on the map's surfaces than they take off (gained - lost > 2 sqrt(lost + gained)):
  // the fit is then registered again from the best such move (the levels that free the scale,
  // no search) and the result kept when it has more inliers; at most this many times in a row.
  int profile_moves = 2;
  // Pitch and roll (turns about the map's horizontal axes) held at the Huber levels (distances
  // above tukey_max_distance_m): their metres-long pairs join points of objects the map lacks
  // (parked cars changed since the survey) to its ground and facades and tilt the structure, a
  // tilt the fine levels then keep (0.76 deg median on the synthetic street with 30 % of the
  // parked cars changed). The seed's tilt is the caller's: the anchors turn it to the road's
  // grade (StructureAnchorOptions::seed_grade).
  bool hold_tilt_coarse = true;
  // The rotation held at the start's at every level (the translation, scale and drift free): for
  // a start whose rotation is known better than the structure fixes it (the anchors' rotation
  // consensus, StructureAnchorOptions::rotation_consensus).
  bool hold_rotation = false;
  double min_inlier_share = 0.0;      // registration fails below this share (checks: caller)
  int min_points = 20;                // fewer points: no registration

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct StructureRegistration {
  bool success = false;  // converged with enough points (else `message` says why)
  std::string message;
  Similarity3 map_from_world;  // the result (the seed when not successful)
  int num_points = 0;          // points given
  int num_inliers = 0;         // within the finest distance at the end
  double inlier_share = 0.0;   // num_inliers / num_points
  double rms_m = 0.0;          // RMS point-to-plane (or -point) distance of the inliers
  int iterations = 0;          // Gauss-Newton iterations over all levels
  Eigen::Vector3d search_offset_m = Eigen::Vector3d::Zero();  // the seed search's best move
  double search_yaw_deg = 0.0;                                // and turn
  // Conditioning along `direction` (RegisterStructure): mean of d^T P_i d over the inliers (the
  // share of their distances that measure along d: (n . d)^2 for a plane; 0: nothing constrains
  // d, 1: everything does), and the standard deviation of the translation (at the structure's
  // centroid) along d, metres, from the final Hessian and residual.
  double along_information = 0.0;
  double along_sigma_m = 0.0;
  // The Hessian's sigma holds only while the pairs do: moved along the road, a street of facades
  // finds other pairs as good. So the fit is also moved along d in steps of the finest distance
  // within the search's reach (search_along_m, also when the search is off; when it is 0, the
  // first correspondence distance), re-paired, and which points lie within the finest level's
  // loss scale of the map's surface compared with the fit's: along_ambiguity_m is the largest
  // move that two paired tests both leave tied with the fit (the reach: nothing fixes it), and
  // along_sigma_m is at least half of it (that interval taken as +-2 sigma). The tests: the
  // points lost from the surface do not outnumber those gained by twice the deviation of the
  // difference (McNemar: lost - gained < 2 sqrt(lost + gained)); and the points' graded costs
  // (squared distance to the surface in units of the loss scale, at most 1) do not rise by twice
  // the deviation of their changes (sum d < 2 sqrt(sum d^2); McNemar's is its case of costs 0
  // and 1). The graded test tells a move whose points stay within the band but move in it: a
  // sparse map's few surfaces facing along the road (synthetic street, a scan every 20 m, 32
  // beams: 18 of 42 anchors fixed, against 3 by the counts alone; the shared KITTI drive: 10
  // and 11 of 16 against 9 and 10).
  double along_ambiguity_m = 0.0;
  int along_points_on_surface = 0;  // the fit's points on the surface in that profile
  double condition = 0.0;           // largest / smallest eigenvalue of the translation block
  // The scale drift estimated (ScaleDriftPath), relative change of scale per metre of road
  // (positive: the structure's scale grows ahead); 0 without a drift model.
  double scale_drift_per_m = 0.0;
  double drift = 0.0;  // the warp's kappa (per world unit) the result's similarity applies to
};

// A linear scale drift of a monocular reconstruction along its camera path. The VO's scale is
// taken to change linearly with the distance travelled, s(x) = s (1 + kappa x), x the arc length
// along the path (world units) from the pivot camera (where the similarity's own scale holds:
// the anchored camera). The camera at arc length x_k then lies at c_k + kappa I_k, I_k = the
// integral of x t(x) dx from the pivot to it (t the unit tangent; x_k^2 / 2 t on a straight
// path), and a point placed from cameras about c_k has its offset from them scaled by
// (1 + kappa x_k): p -> p + kappa a(p), a(p) = x_k (p - c_k) + I_k. Linear in kappa; the pivot
// and the orientation there do not move.
class ScaleDriftPath {
 public:
  // `centres`: the path's camera centres in order (world frame); `pivot`: index of the pivot.
  ScaleDriftPath(std::vector<Eigen::Vector3d> centres, size_t pivot);
  // a(point) for a point placed from the path's camera `reference` (an index into centres).
  Eigen::Vector3d Direction(const Eigen::Vector3d& point, size_t reference) const;
  // The position of camera `index` under a drift kappa (c_k + kappa I_k).
  Eigen::Vector3d Camera(size_t index, double kappa) const;
  size_t size() const { return centres_.size(); }

 private:
  std::vector<Eigen::Vector3d> centres_;
  std::vector<double> arc_;                // x_k
  std::vector<Eigen::Vector3d> integral_;  // I_k
};

// The scale drift RegisterStructure applies to (or estimates for) its points.
struct StructureDrift {
  std::vector<Eigen::Vector3d> directions;  // a(p) of each point (ScaleDriftPath::Direction)
  double per_m = 0.0;     // the drift, relative change of scale per metre (the start, estimating)
  bool estimate = false;  // estimated at the levels that free the scale (within
                          // +-StructureRegistrationOptions::max_scale_drift_per_m)
};

// The map with a kd-tree over its points and normals computed on demand. Not thread-safe (the
// normal cache); one per thread.
class StructureMap {
 public:
  // Copies the positions of `cloud` (intensity and colour are not used).
  explicit StructureMap(const PointCloud& cloud, const StructureRegistrationOptions& options);
  ~StructureMap();
  StructureMap(const StructureMap&) = delete;
  StructureMap& operator=(const StructureMap&) = delete;

  size_t size() const;
  // Index of the nearest map point within max_distance_m of `x`, or -1.
  int Nearest(const Eigen::Vector3d& x, double max_distance_m) const;
  // The same for many points at once (faster).
  std::vector<int> Nearest(const std::vector<Eigen::Vector3d>& x, double max_distance_m) const;
  // Whether the map has a point in the cube of side search_truncation_m / 2 (a grid aligned
  // with the map frame's axes) that holds `x`, or in the cubes within search_height_m above or
  // below it: the seed search's score.
  bool Occupied(const Eigen::Vector3d& x) const;
  const Eigen::Vector3f& Point(int index) const;
  // Projector of the distance to the map's surface at point `index` (see the top of the file):
  // n n^T for a plane, I - a a^T for a line along a, I for a point.
  const Eigen::Matrix3f& Projector(int index);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Registers `points_in_world` to `map` from the seed `initial` (see the top of the file);
// `direction` (unit, map frame; e.g. the road's) is where the conditioning is reported. With
// `drift`, the points are warped by its drift (the result's similarity maps p + kappa a(p)), and
// with drift->estimate the drift is estimated too. Expected failures (too few points or pairs)
// come back with success = false.
StructureRegistration RegisterStructure(const std::vector<Eigen::Vector3d>& points_in_world,
                                        StructureMap& map,
                                        const Similarity3& initial,
                                        const Eigen::Vector3d& direction,
                                        const StructureRegistrationOptions& options,
                                        const StructureDrift* drift = nullptr);

}  // namespace epiloc
