// The structure anchors' parts shared by structure_anchor.cc (one frame, the drive) and
// structure_passes.cc (the passes over all anchors: drift, consensus). Not installed.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/cloud/point_cloud.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {
namespace structure_internal {

// The map near a position: (centre in the map frame, radius) -> points, voxel-filtered.
using MapLoader = std::function<PointCloud(const Eigen::Vector3d&, double)>;

// A registration again from a given similarity (no search), over the given correspondence
// distances, with a given scale drift.
struct Restart {
  Similarity3 sim;
  double drift_per_m = 0.0;
  std::vector<double> levels_m;
  bool hold_rotation = false;
};

// Of two fits of one structure, whether the first is the better: more of its points on the map's
// surfaces, then the smaller RMS residual (the first pass's choice among its seeds, and the fits'
// exchange's among the neighbours' fits).
inline bool FitsBetter(int inliers_a, double rms_a, int inliers_b, double rms_b) {
  if (inliers_a != inliers_b) return inliers_a > inliers_b;
  return rms_a < rms_b;
}

// What anchoring a drive's frames shares: the drive, its frames to anchor (`indices` into
// drive.frames), their VO poses (`pose_of`: per drive frame its index in vo.poses, or -1), the map
// and the options.
struct DriveAnchoring {
  const Drive& drive;
  const std::vector<size_t>& indices;
  const std::vector<int>& pose_of;
  const VoStructure& vo;
  const MapLoader& load;
  const EnuFrame& map_frame;
  const StructureAnchorOptions& options;
};

// Puts an anchor's camera centre at `centre` (map frame), with its WGS-84 position and its
// rotation in the local ENU there.
void SetCentre(const EnuFrame& map_frame, const Eigen::Vector3d& centre, AnchorResult* a);
// Moves an ok anchor's camera horizontally to `xy` (map frame), its height kept (the ground under
// it moves by the road's grade times the move, a few millimetres), and its prior offset with it.
// Returns the horizontal move, metres.
double MoveHorizontally(const DriveAnchoring& run, const Eigen::Vector2d& xy, AnchorResult* a);

// The drive's GNSS position at time `t` in the map frame; none beyond the drive's max_gap_s.
std::optional<Eigen::Vector3d> GnssInMap(const DriveAnchoring& run, double t);

// Anchors drive.frames[index]; see the top of structure_anchor.h. With `restart`, from its
// similarity instead of the GPS seed.
AnchorResult AnchorOne(const DriveAnchoring& run, size_t index, const Restart* restart = nullptr);

// The similarity VO world -> map an anchored frame's pose implies.
Similarity3 ImpliedSimilarity(const AnchorResult& a, const Rigid3d& world_from_cam);

// Least-squares slope of y over x of `xy`; nullopt with fewer than `min_samples` points or an x
// spread below `min_spread`.
std::optional<double> LeastSquaresSlope(const std::vector<Eigen::Vector2d>& xy,
                                        size_t min_samples,
                                        double min_spread);

// The drift pass (ScaleDriftModel::kAcrossAnchors) over `out` (one result per run.indices): the
// VO's scale drift at each posed anchor from the scales of the anchors around it, then each
// registered again from its own fit with its structure warped by that drift; in two rounds, the
// second's drift from the first round's scales, registered from the fits of `out`.
void ApplyDriftAcrossAnchors(const DriveAnchoring& run, AnchorDriveResult* out);

// The fits' exchange (StructureAnchorOptions::exchange_rounds) over `out`, before the drift
// pass: each posed anchor registered again from the similarities of its neighbours that fit
// their own windows better and place its camera elsewhere; the fit with most inliers is kept.
void ExchangeFits(const DriveAnchoring& run, AnchorDriveResult* out);

// The passes after the drift pass, in this order (structure_passes.cc): the consensus pass
// (StructureAnchorOptions::consensus_radius_m), the rotation consensus
// (StructureAnchorOptions::rotation_consensus), then the neighbours' check of the ok anchors
// (also consensus_radius_m). The rotation consensus registers each posed anchor again with the
// consensus over placement_rotation_radius_m held and returns, per result of `out`, the
// consensus over window_m that turns its camera (nullopt: not posed), for OrientByConsensus.
void ApplyConsensus(const DriveAnchoring& run, AnchorDriveResult* out);
std::vector<std::optional<Eigen::Quaterniond>> ApplyRotationConsensus(const DriveAnchoring& run,
                                                                      AnchorDriveResult* out);
void GateByNeighbours(const DriveAnchoring& run, AnchorDriveResult* out);
// Then the consensus placement of the ok anchors (StructureAnchorOptions::consensus_placement).
void PlaceByConsensus(const DriveAnchoring& run, AnchorDriveResult* out);
// Last: each posed anchor with an orientation (one per result of `out`; empty: none) gets the
// camera rotation orientation * its VO orientation, its centre kept.
void OrientByConsensus(const DriveAnchoring& run,
                       const std::vector<std::optional<Eigen::Quaterniond>>& orientations,
                       AnchorDriveResult* out);

// The map bundle (StructureAnchorOptions::map_bundle; structure_bundle.cc): the cameras of
// anchors' windows and the points they saw (VoPoint::seen), placed by the anchors' implied
// similarities, adjusted together: the sightings' reprojection errors, the points' distances
// from the map's local planes and each anchor's centre held where it was placed.
struct MapBundleResult {
  bool success = false;
  Eigen::Quaterniond map_from_cam = Eigen::Quaterniond::Identity();  // the anchor's camera
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();                  // and its centre
  int cameras = 0;
  int points = 0;
  int points_on_map = 0;  // with a plane residual at the last distance
  int iterations = 0;
};
// Throws Error naming the first invalid map_bundle option (StructureAnchorOptions::Check).
void CheckMapBundleOptions(const StructureAnchorOptions& options);
// For the results `ks` of a run (run.indices[k]) with their anchors (one per k), adjusted
// together: the cameras within bundle_window_m / 2 of any of them, each anchor's centre held.
// Only the ok ones (status) place the window and hold the gauge; one that is not takes the
// rotation of its frame's camera when the window holds it. One result per k; not successful
// without a pose, sightings, a map or enough points on it, or in another segment than the first
// ok one.
std::vector<MapBundleResult> AdjustWindowsToMap(const DriveAnchoring& run,
                                                const std::vector<size_t>& ks,
                                                const std::vector<AnchorResult>& anchors);
// The same for the `k`th result alone.
MapBundleResult AdjustWindowToMap(const DriveAnchoring& run, size_t k, const AnchorResult& a);
// Last: the posed anchors of `out` in chunks (consecutive, one segment, within bundle_chunk_m of
// the chunk's first), each chunk adjusted together; each anchor takes its camera's rotation, its
// centre kept.
void RefineByMapBundle(const DriveAnchoring& run, AnchorDriveResult* out);

}  // namespace structure_internal
}  // namespace epiloc
