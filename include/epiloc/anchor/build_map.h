// Map assembly (`epiloc build-map`): a drive's LiDAR scans merged with their poses into one
// voxel-filtered point cloud in a local ENU frame, optionally coloured from the drive's camera
// frames, written with its sidecar (map_sidecar.h).
//
// Scan points (sensor frame) go to the map frame through the scan's pose: the sensor's WGS-84
// position and enu_from_sensor in the local ENU at that position (drive.h, LidarScan), moved
// exactly into the map's ENU frame. Points closer than min_range_m (the vehicle) or farther than
// max_range_m from the sensor are dropped; the merge is voxel-filtered (voxel.h: centroid, mean
// intensity) scan by scan, so memory holds one record per occupied voxel, never all raw points.
//
// Colouring (occlusion-aware): each (every frame_step-th) camera frame with a pose is undistorted
// and the map is rendered into it (render.h) for a depth buffer; a point takes a colour from the
// frame only if it projects inside the image (off the border), lies within max_range_m of the
// camera, and is not behind the rendered surface at its pixel:
//     z <= depth * (1 + occlusion_rel) + occlusion_abs_m
// (the relative term absorbs splats of oblique surfaces such as the road). Each sample is
// area-averaged over the point's footprint in the image (footprint_m * fx / z pixels, from an
// image pyramid, like a mipmap), so near and far frames agree and a near frame does not give an
// aliased single pixel. Mode kAverage: the mean of the samples of all frames that see the point;
// kClosest: the sample of the
// frame whose camera centre is nearest (sharpest, no blur from pose or timing errors between
// frames). Points no frame sees are dropped unless keep_uncoloured (then grey 128).
// Camera poses for colouring come from the ground truth (or, lacking it, the GNSS) and must carry
// orientations.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/cloud/point_cloud.h"
#include "epiloc/cloud/render.h"
#include "epiloc/core/progress.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {

enum class ColourMode {
  kAverage,  // mean colour over the frames that see the point
  kClosest,  // colour from the frame whose camera is closest to the point
};
// "average", "closest"; ParseColourMode throws Error for another name.
std::string ColourModeName(ColourMode mode);
ColourMode ParseColourMode(const std::string& name);

struct MapColourOptions {
  ColourMode mode = ColourMode::kClosest;  // how the frames' samples are combined
  int frame_step = 1;                      // colour from every n-th frame of the drive
  double min_range_m = 0.0;        // a frame colours points at least this far from its camera
  double max_range_m = 40.0;       // a frame colours points at most this far from its camera
  double occlusion_rel = 0.05;     // visibility test (see the top of the file), relative part
  double occlusion_abs_m = 0.10;   // ... and absolute part, metres
  int border_px = 2;               // samples within this many pixels of the image edge are not used
  double footprint_m = 0.05;       // surface size a point stands for (the voxel side): colours
                                   // are averaged over its footprint in the image (mipmap)
  bool keep_uncoloured = false;    // keep points no frame sees (grey 128) instead of dropping them
  CloudRenderOptions render;       // the occlusion depth buffer's rendering

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct BuildMapOptions {
  double voxel_m = 0.05;      // voxel side of the filter, metres (0 = keep every point)
  double min_range_m = 3.0;   // scan points closer to the sensor are dropped (the vehicle)
  double max_range_m = 80.0;  // scan points farther from the sensor are dropped
  // Motion compensation of spinning LiDAR scans (0 = off): a point at azimuth phi (sensor frame,
  // counter-clockwise from x) was measured at t_scan + tau, tau = -phi / 2 pi * period for a
  // clockwise spin (seen from above; +phi / 2 pi * period counter-clockwise), t_scan being the
  // time the beam pointed along x (KITTI's velodyne timestamps.txt; HDL-64E: period 0.1 s,
  // clockwise). The sensor's motion over tau comes from the drive's oriented camera track.
  double deskew_period_s = 0.0;
  bool spin_clockwise = true;
  bool colorize = false;      // colour the map from the drive's camera frames
  MapColourOptions colour;
  int num_threads = 2;  // scans read / frames projected in parallel

  // Throws Error naming the first invalid field.
  void Check() const;
};

struct BuildMapSummary {
  std::string drive_name;
  int64_t num_scans = 0;             // scans merged
  int64_t num_points_in = 0;         // scan points kept by the range filter
  int64_t num_points_out = 0;        // points in the map written
  int64_t num_colour_frames = 0;     // frames that coloured the map
  int64_t num_coloured_points = 0;   // map points coloured by at least one frame
  int64_t num_dropped_uncoloured = 0;
  Bounds3f bounds;                   // of the map's points, metres in its ENU frame
  Geodetic enu_origin;
  double seconds = 0.0;
};

// Merges the scans of `drive` into `map_frame` (see the top of the file). Throws Error naming the
// drive when it has no scans, and naming a scan file that is unreadable. `progress` gets (scans
// done, scans). `summary` (optional) receives num_scans, num_points_in.
PointCloud MergeScans(const Drive& drive,
                      const EnuFrame& map_frame,
                      const BuildMapOptions& options,
                      const ProgressCallback& progress = nullptr,
                      BuildMapSummary* summary = nullptr);

// Colours `cloud` (in `map_frame`) from the frames of `drive` (see the top of the file); sets
// cloud->rgb and may drop points. Throws Error when the drive has no camera poses with
// orientation, or a frame cannot be read. `progress` gets (frames done, frames).
void ColorizeCloud(const Drive& drive,
                   const EnuFrame& map_frame,
                   const MapColourOptions& options,
                   int num_threads,
                   PointCloud* cloud,
                   const ProgressCallback& progress = nullptr,
                   BuildMapSummary* summary = nullptr);

// How well a drive's scans agree when its track is stretched: the scans merged as MergeScans
// does, with each scan's horizontal offset from the first scan's position multiplied by a factor
// (1 +- max_stretch in steps of `step`; heights and orientations kept). Scans share surfaces (a
// facade, a pole, a car seen from several places); a track whose positions are too short or too
// long draws each shared surface several times, a little apart, so it gets thicker. Over cells of
// 0.5 m (a patch of surface holding several scan lines of each scan) that hold at least 10 points
// of two or more scans, the mean thickness (square root of the smallest eigenvalue of the points'
// covariance) is computed for each factor; the factor with the thinnest surfaces is the stretch of
// the track the LiDAR agrees with (surfaces a shift slides onto themselves, as the road, do not
// change; counting occupied voxels instead favours any shrinking, which shrinks the map). A
// GNSS/INS track with slow position errors can be off by percents over a short drive (KITTI
// 2011_09_26_drive_0005, see README), and every map, database and ground truth built from it
// inherits that. Uses at most max_points scan points (every k-th of each scan). Throws Error as
// MergeScans does, and naming an invalid argument.
struct TrackScaleCheck {
  std::vector<double> factors;         // stretch factors tried, ascending
  std::vector<double> thickness_m;     // mean thickness of the shared surface cells per factor
  std::vector<int64_t> shared_voxels;  // cells with points of two or more scans per factor
  double best_factor = 1.0;  // the thinnest surfaces, refined by a parabola through its neighbours
  double voxel_m = 0.0;      // cell side
  int64_t num_points = 0;    // scan points used
  int64_t num_scans = 0;
  double span_m = 0.0;  // largest horizontal distance of a scan from the first
};
TrackScaleCheck CheckTrackScale(const Drive& drive,
                                const EnuFrame& map_frame,
                                const BuildMapOptions& options,
                                double max_stretch = 0.06,
                                double step = 0.005,
                                int64_t max_points = 4000000);

// Builds the map of the drive in `drive_dir` and writes it to `out_path` (any format
// WritePointCloud writes; PLY recommended) with the sidecar SidecarPath(out_path). The ENU origin
// is `origin` (described by `origin_source`, e.g. "database route.sqlite"), or, when nullopt,
// the drive's first position (first ground-truth sample, else first GNSS sample, else first scan
// position). `progress` gets (units done, total) over scans and colour frames.
BuildMapSummary BuildMap(const std::string& drive_dir,
                         const std::string& out_path,
                         const std::optional<Geodetic>& origin,
                         const std::string& origin_source,
                         const BuildMapOptions& options,
                         const ProgressCallback& progress = nullptr);

}  // namespace epiloc
