// The structure anchors' parts shared by structure_anchor.cc (one frame, the drive) and
// structure_passes.cc (the passes over all anchors: drift, consensus). Not installed.
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Core>

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
};

// Anchors the frame drive.frames[index] (pose_of: its VO pose index per drive frame, or -1); see
// the top of structure_anchor.h. With `restart`, from its similarity instead of the GPS seed.
AnchorResult AnchorOne(const Drive& drive,
                       size_t index,
                       const std::vector<int>& pose_of,
                       const VoStructure& vo,
                       const MapLoader& load,
                       const EnuFrame& map_frame,
                       const StructureAnchorOptions& options,
                       const Restart* restart = nullptr);

// The similarity VO world -> map an anchored frame's pose implies.
Similarity3 ImpliedSimilarity(const AnchorResult& a, const Rigid3d& world_from_cam);

// The drift pass (ScaleDriftModel::kAcrossAnchors): the VO's scale drift at each posed anchor of
// `out` (frames `indices` of `drive`) from the scales of the anchors around it, then each
// registered again from its own fit with its structure warped by that drift.
void ApplyDriftAcrossAnchors(const Drive& drive,
                             const std::vector<size_t>& indices,
                             const std::vector<int>& pose_of,
                             const VoStructure& vo,
                             const MapLoader& load,
                             const EnuFrame& map_frame,
                             const StructureAnchorOptions& options,
                             AnchorDriveResult* out);

// The consensus pass (StructureAnchorOptions::consensus_radius_m; structure_passes.cc).
void ApplyConsensus(const Drive& drive,
                    const std::vector<size_t>& indices,
                    const std::vector<int>& pose_of,
                    const VoStructure& vo,
                    const MapLoader& load,
                    const EnuFrame& map_frame,
                    const StructureAnchorOptions& options,
                    AnchorDriveResult* out);

}  // namespace structure_internal
}  // namespace epiloc
