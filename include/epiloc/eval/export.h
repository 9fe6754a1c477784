// Export of result trajectories for other tools (evo, GIS): `epiloc export`. Only rows with
// status ok are exported, in time order.
//
// Formats:
//  - tum: "t x y z qx qy qz qw" per line; x, y, z east/north/up metres about the origin; the
//    quaternion is enu_from_cam (camera x right, y down, z forward) in the origin's ENU axes.
//  - kitti: 12 numbers per line, row-major 3x4 [R | t] = world_from_cam, the world frame being the
//    axes of a level camera at the origin looking north (x east, y down, z north), i.e. the
//    convention ReadTruth assumes for kitti_poses with yaw 0, so that an export reads back with
//    `--truth-format kitti_poses --truth-origin <origin>`. Timestamps go to
//    "<out without extension>_times.txt", one per line.
//  - geojson: a FeatureCollection; per method a LineString (properties: method, kind "track",
//    frames) and a Point per row (properties: method, frame, timestamp_s, status, s_m, db_frame
//    and the extra columns). Coordinates [lon, lat, alt].
//  - kml: per method a Placemark with the LineString and a Folder of point Placemarks.
//  - gpx: GPX 1.1, a track per method; <time> (UTC, ISO 8601) only when timestamps look like UNIX
//    time (between 1973 and 2100).
// Orientation of tum/kitti poses: the row's qw..qz when present, else from the direction of
// travel (central difference of the neighbouring positions): camera looking along the horizontal
// travel direction, level (x right, y down). Rows at a standstill take the last direction.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "epiloc/geo/geodetic.h"
#include "epiloc/io/result.h"

namespace epiloc {

enum class TrajectoryFormat { kTum, kKitti, kGeoJson, kKml, kGpx };

// "tum", "kitti", "geojson", "kml", "gpx"; unknown names throw Error.
TrajectoryFormat ParseTrajectoryFormat(const std::string& name);
std::string TrajectoryFormatName(TrajectoryFormat format);

struct ExportOptions {
  TrajectoryFormat format = TrajectoryFormat::kGeoJson;
  std::string method;              // empty: all methods (tum/kitti: the file must have only one)
  std::optional<Geodetic> origin;  // of tum/kitti coordinates; default: the first exported row
};

struct ExportSummary {
  std::vector<std::string> methods;  // exported
  int64_t rows = 0;                  // positions written
  Geodetic origin;                   // used by tum/kitti
  std::string times_path;            // kitti: the timestamps file
};

// Writes `table` to `out_path` in options.format. Throws Error naming the result file when the
// method is absent, has no ok rows, or tum/kitti is asked for several methods.
ExportSummary ExportTrajectory(const ResultTable& table,
                               const ExportOptions& options,
                               const std::string& out_path);

// "YYYY-MM-DDTHH:MM:SS.sssZ" of UNIX seconds; nullopt outside 1973..2100.
std::optional<std::string> IsoTimeOfUnixSeconds(double timestamp_s);

}  // namespace epiloc
