// The path of a drive's LiDAR scans from the scans themselves (LiDAR odometry), against the
// position track they were placed with.
//
// A GNSS/INS unit's attitude is usually better than its position track: on KITTI
// 2011_09_26_drive_0005 the turn between consecutive scans that the unit reports agrees with the
// scans' own (ICP) turn within 0.1 deg, but its positions step 3.6 % short of the scans' steps and
// its direction of travel differs from the scans' by -0.4 deg in pitch (the track climbs 0.5 m
// less over 70 m) and by up to 2.6 deg in heading (README). A map placed with those positions
// draws each surface several times, a little apart, and a camera pose from the same track (the
// ground truth) disagrees with that map by as much: decimetres along the road and half a degree,
// more than the anchors' targets.
//
// EstimateLidarTrack registers each scan to the one before it (point-to-plane ICP, metric: the
// scale held, RegisterStructure), seeded by the track's relative pose. The path is the sum of the
// registered steps, each turned into the map frame by the track's attitude at the earlier scan
// (the attitude is kept: a chain of ICP turns drifts, the unit's attitude does not). The path is
// placed so that its mean offset from the track's scan positions is zero (the LiDAR knows the
// shape, not where on the Earth it lies). A pair that does not register (too few points on the
// other's surfaces, see LidarTrackOptions) keeps the track's own step.
//
// CorrectDriveTrack moves the scans to that path and every ground-truth sample by the correction
// interpolated in time between the scans (held constant before the first scan and after the
// last): the track the drive's LiDAR agrees with, for a map and a ground truth that agree with
// each other. The GNSS is left alone (it is the sensor under test).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/core/progress.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {

struct LidarTrackOptions {
  double min_range_m = 3.0;   // scan points closer to the sensor are dropped (the vehicle)
  double max_range_m = 40.0;  // ... and farther (sparse rings that pair badly)
  double voxel_m = 0.15;      // scans thinned to one point per voxel of this side
  // Correspondence distances from coarse to fine (RegisterStructure): the first bounds the seed's
  // error the registration corrects (a track's step is off by centimetres to decimetres).
  std::vector<double> max_distances_m = {1.0, 0.5, 0.3, 0.2};
  // A pair whose later scan has fewer of its points within the finest distance of the earlier
  // scan's surfaces keeps the track's step: consecutive scans share most of what they see, so a
  // registration with less has locked onto something else (or the scans barely overlap).
  double min_inlier_share = 0.3;
  int num_threads = 2;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// One pair of consecutive scans.
struct LidarTrackStep {
  int64_t from_scan = -1;  // the drive's scan numbers
  int64_t to_scan = -1;
  bool registered = false;  // false: the track's step is kept (`message` says why)
  std::string message;
  double inlier_share = 0.0;
  double rms_m = 0.0;
  double lidar_m = 0.0;  // the step's length from the scans
  double track_m = 0.0;  // ... and from the track
  // Direction of the track's step minus the scans', degrees, in the earlier scan's sensor frame
  // (pitch: elevation above its x-y plane; heading: azimuth about its z axis).
  double pitch_deg = 0.0;
  double heading_deg = 0.0;
  double turn_difference_deg = 0.0;  // angle between the track's turn and the scans' turn
  // The track's turn minus the scans' about the earlier scan's up (z) axis, degrees, signed
  // (positive: the track turns further to the left, counter-clockwise seen from above).
  double yaw_difference_deg = 0.0;
};

struct LidarTrack {
  std::vector<int64_t> scans;                 // the drive's scan numbers, in drive order
  std::vector<double> timestamps_s;           // their times
  std::vector<Eigen::Vector3d> correction_m;  // LiDAR path minus track position, map frame
  std::vector<LidarTrackStep> steps;          // scans.size() - 1 pairs
  int num_registered = 0;
  double lidar_length_m = 0.0;      // sum of the registered steps' lengths, from the scans
  double track_length_m = 0.0;      // ... and from the track
  double median_pitch_deg = 0.0;    // over the registered steps longer than 0.5 m
  double median_heading_deg = 0.0;  // (shorter ones have no direction to speak of)
  double max_abs_pitch_deg = 0.0;   // and the largest of each, in size
  double max_abs_heading_deg = 0.0;
  double max_turn_difference_deg = 0.0;
  // The registered steps' yaw differences summed from the first scan: how far the track's
  // heading (its attitude, e.g. an INS's) has turned away from the scans' by each scan
  // (cumulative_yaw_deg, one per scan, 0 at the first), and the largest of it in size. A track
  // whose heading is right keeps this within the scans' own registration noise (hundredths of a
  // degree per pair); a heading that over- or under-turns shows as a ramp through the turns.
  std::vector<double> cumulative_yaw_deg;
  double max_abs_cumulative_yaw_deg = 0.0;
  double max_correction_m = 0.0;  // largest |correction_m|
};

// See the top of the file. `map_frame` is any ENU frame near the drive (corrections are
// expressed in it). Throws Error when the drive has fewer than two scans or a scan is unreadable.
// `progress` gets (pairs done, pairs).
LidarTrack EstimateLidarTrack(const Drive& drive,
                              const EnuFrame& map_frame,
                              const LidarTrackOptions& options,
                              const ProgressCallback& progress = nullptr);

// The drive with its scans and ground truth moved by `track` (see the top of the file); the
// orientations are kept. The drive may be another import of the same recording (another camera)
// holding some of the track's scans. Throws Error when one of its scans is not in `track` (by
// number and time).
Drive CorrectDriveTrack(const Drive& drive, const EnuFrame& map_frame, const LidarTrack& track);

}  // namespace epiloc
