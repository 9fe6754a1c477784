// Helpers shared by the anchor module's sources (not installed).
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "epiloc/anchor/anchor.h"
#include "epiloc/camera/camera.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/tiled_cloud.h"
#include "epiloc/core/angles.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"

namespace epiloc {
namespace anchor_internal {

// The cloud format of a drive's scan file (`path`: the scan's resolved path, for messages).
CloudFormat ScanFormat(const LidarScan& scan, const std::string& path);

// A drive's scan (sensor frame) with the points closer than min_range_m or farther than
// max_range_m from the sensor dropped; intensity when asked for and present, never colour.
PointCloud ReadScanInRange(const Drive& drive,
                           const LidarScan& scan,
                           double min_range_m,
                           double max_range_m,
                           bool with_intensity);

// map_from_cam of a camera whose position sample (WGS-84 centre, enu_from_cam in the local ENU
// at that position) is expressed in the map's ENU frame.
inline Rigid3d MapFromSample(const EnuFrame& map_frame,
                             const Geodetic& position,
                             const Eigen::Quaterniond& local_enu_from_x) {
  return Rigid3d::FromMatrix(map_frame.EnuFromLocalEnu(position) *
                                 local_enu_from_x.normalized().toRotationMatrix(),
                             map_frame.ToEnu(position));
}

// Pitch (optical axis above the horizon) and roll (x axis below it) of a camera, degrees.
inline std::pair<double, double> PitchRollDeg(const Eigen::Matrix3d& map_from_cam) {
  const double pitch = std::asin(std::clamp(map_from_cam(2, 2), -1.0, 1.0)) * kRadToDeg;
  const double roll = std::asin(std::clamp(-map_from_cam(2, 0), -1.0, 1.0)) * kRadToDeg;
  return {pitch, roll};
}

// The drive's camera poses with orientation: the ground truth if all its samples have one, else
// the GNSS if all of its have; nullptr if neither.
inline const PositionTrack* OrientedTrack(const Drive& drive) {
  const auto oriented = [](const PositionTrack& track) {
    if (track.samples.empty()) return false;
    for (const PositionSample& s : track.samples) {
      if (!s.enu_from_cam) return false;
    }
    return true;
  };
  if (drive.ground_truth && oriented(*drive.ground_truth)) return &*drive.ground_truth;
  if (oriented(drive.gnss)) return &drive.gnss;
  return nullptr;
}

// Indices (drive order) of the frames `inputs` selects (frames, else every `every`-th). Throws
// Error for a frame number not in the drive.
std::vector<size_t> SelectFrames(const AnchorInputs& inputs, const Drive& drive);

// Opens a map for loading near poses: a tile directory as is; a single file whole when it holds
// at most `max_whole_points` points, else cut once into a tile cache `tile_dir` (default
// <cloud>.tiles), reused while it is newer than the file. Throws Error naming the path.
std::unique_ptr<TiledCloud> OpenMap(const std::string& cloud_path,
                                    const std::string& tile_dir,
                                    int64_t max_whole_points);

// Throws Error naming the cloud when its bounds lie more than `max_distance_m` (horizontally)
// from every GNSS (else ground-truth) position of the drive: it is in another frame.
void CheckMapNearDrive(const std::string& cloud_path,
                       const TiledCloud& map,
                       const EnuFrame& map_frame,
                       const Drive& drive,
                       double max_distance_m);

}  // namespace anchor_internal
}  // namespace epiloc
