// The frame of a LiDAR map travels with the file: a JSON sidecar `<cloud>.json` beside the cloud
// (map.ply -> map.ply.json; a tile directory map.tiles -> map.tiles.json) written by
// `epiloc build-map` and read by `render` and `anchor`.
//
// Sidecar format (version 1):
//   {"format": "epiloc-map", "version": 1,
//    "enu_origin": {"lat_deg": 49.011, "lon_deg": 8.4229, "alt_m": 113.6},
//    "origin_source": "database route.sqlite" | "first position of drive ..." | "given",
//    "source_drive": "kitti_2011_09_26_0005_cam0", "source_dir": "/abs/survey0",
//    "voxel_m": 0.05, "num_points": 1234567, "num_scans": 31,
//    "attributes": ["intensity", "rgb"],
//    "colour": {"mode": "closest", "frames": 154, "coloured_points": 1000000},   (optional)
//    "bounds": {"min": [x, y, z], "max": [x, y, z]},
//    "created_by": "epiloc 0.1.0"}
// Positions of the cloud are metres in the local ENU frame about `enu_origin` (x east, y north,
// z up). Unknown keys are kept out (an error), so a typo does not pass silently.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/cloud/point_cloud.h"
#include "epiloc/geo/geodetic.h"

namespace epiloc {

struct MapSidecar {
  Geodetic enu_origin;        // origin of the cloud's ENU frame (WGS-84 degrees, metres)
  std::string origin_source;  // how the origin was chosen (informative)
  std::string source_drive;   // name of the drive the map was built from ("" if unknown)
  std::string source_dir;     // its directory
  double voxel_m = 0.0;       // voxel side of the filter applied, metres (0 = none)
  int64_t num_points = 0;
  int64_t num_scans = 0;
  std::vector<std::string> attributes;  // "intensity", "rgb" (those the cloud has)
  std::string colour_mode;              // "", "average" or "closest" (how rgb was made)
  int64_t colour_frames = 0;            // camera frames that coloured the map
  int64_t coloured_points = 0;          // points that took a colour from at least one frame
  Bounds3f bounds;                      // of the points, metres
  std::string created_by;               // "epiloc <version>"
};

// `cloud_path` + ".json" (a trailing '/' of a directory removed first).
std::string SidecarPath(const std::string& cloud_path);

// Writes / reads a sidecar. Reading throws Error naming the file for malformed JSON, a wrong
// format or version, an unknown key, a missing origin or an origin out of range.
void WriteMapSidecar(const MapSidecar& sidecar, const std::string& path);
MapSidecar ReadMapSidecar(const std::string& path);

// A sidecar for `cloud` (its point count, attributes and bounds) in the ENU frame about
// `enu_origin`, created_by this build; the caller fills in the source and the scans.
MapSidecar DescribeCloud(const PointCloud& cloud,
                         const Geodetic& enu_origin,
                         const std::string& origin_source);

// The sidecar of `cloud_path` if one exists (nullopt otherwise).
std::optional<MapSidecar> FindMapSidecar(const std::string& cloud_path);

// Parses "LAT,LON,ALT" (degrees, degrees, metres). Throws Error "--cloud-origin 'x': ..." for a
// malformed or out-of-range value.
Geodetic ParseGeodetic(const std::string& text, const std::string& option_name);

// Where a cloud's ENU origin comes from, in order of precedence: an explicit origin
// (--cloud-origin), the sidecar, a route database's ENU origin (--db).
struct MapOriginInputs {
  std::string cloud_path;
  std::optional<Geodetic> explicit_origin;  // --cloud-origin
  std::string db_path;                      // --db ("" = none)
};
struct MapOrigin {
  Geodetic enu_origin;
  std::string source;                // "--cloud-origin", "sidecar <path>", "database <path>"
  std::optional<MapSidecar> sidecar;  // when there is one
};
// Resolves the origin; a lower-precedence source that disagrees by more than 1 mm is logged as a
// warning. Without any: Error "<cloud>: no sidecar <cloud>.json; give --cloud-origin
// LAT,LON,ALT or --db ROUTE.sqlite".
MapOrigin ResolveMapOrigin(const MapOriginInputs& inputs);

// The ENU origin of a route database (Error naming it when it has none).
Geodetic DatabaseEnuOrigin(const std::string& db_path);

}  // namespace epiloc
