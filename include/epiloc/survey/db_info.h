// A summary of a route database for `epiloc info`.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/geo/geodetic.h"

namespace epiloc {

struct DriveInfo {
  std::string name;
  std::string positions;  // where frame positions came from
  int64_t num_frames = 0;
  int64_t num_frames_planned = 0;
  bool complete = false;
  double s_min_m = 0.0;  // along-route span covered by the drive's frames
  double s_max_m = 0.0;
  int width = 0;  // feature camera
  int height = 0;
};

struct DatabaseInfo {
  std::string path;
  int schema_version = 0;
  std::optional<Geodetic> enu_origin;
  std::vector<DriveInfo> drives;
  int64_t num_frames = 0;
  int64_t num_features = 0;
  int min_features_per_frame = 0;
  double mean_features_per_frame = 0.0;
  int max_features_per_frame = 0;
  double route_length_m = 0.0;
  int64_t num_points = 0;        // triangulated 3-D points (schema version >= 3)
  int64_t num_observations = 0;  // and their observations
  int64_t file_bytes = 0;  // database file plus its WAL
};

// Reads the summary (read-only; never migrates). Throws Error for a missing or invalid file.
DatabaseInfo SummarizeDatabase(const std::string& db_path);
// Human-readable multi-line text of the summary.
std::string FormatDatabaseInfo(const DatabaseInfo& info);

}  // namespace epiloc
