#include "epiloc/survey/db_info.h"

#include <algorithm>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "epiloc/core/error.h"
#include "epiloc/db/database.h"
#include "epiloc/geo/route.h"

namespace epiloc {

DatabaseInfo SummarizeDatabase(const std::string& db_path) {
  namespace fs = std::filesystem;
  if (!fs::exists(db_path)) Throw("{}: no such database", db_path);
  Database db(db_path, Database::Mode::kReadOnly);
  DatabaseInfo info;
  info.path = db_path;
  info.schema_version = db.SchemaVersion();
  info.enu_origin = db.EnuOrigin();
  const std::vector<Eigen::Vector3d> route = db.ReadRoute();
  if (route.size() >= 2) info.route_length_m = Route(route).length_m();

  int min_features = std::numeric_limits<int>::max();
  for (const DbDrive& drive : db.ReadDrives()) {
    DriveInfo d;
    d.name = drive.name;
    d.positions = drive.positions;
    d.num_frames_planned = drive.num_frames_planned;
    d.complete = drive.complete;
    const DbCamera camera = db.ReadCamera(drive.camera_id);
    d.width = camera.camera.width;
    d.height = camera.camera.height;
    const std::vector<DbFrame> frames = db.ReadFrames(drive.drive_id);
    d.num_frames = static_cast<int64_t>(frames.size());
    if (!frames.empty()) {
      d.s_min_m = d.s_max_m = frames.front().s_m;
    }
    for (const DbFrame& frame : frames) {
      d.s_min_m = std::min(d.s_min_m, frame.s_m);
      d.s_max_m = std::max(d.s_max_m, frame.s_m);
      info.num_features += frame.num_features;
      min_features = std::min(min_features, frame.num_features);
      info.max_features_per_frame = std::max(info.max_features_per_frame, frame.num_features);
    }
    info.num_frames += d.num_frames;
    info.drives.push_back(d);
  }
  if (info.num_frames > 0) {
    info.min_features_per_frame = min_features;
    info.mean_features_per_frame = static_cast<double>(info.num_features) / info.num_frames;
  }
  if (info.schema_version >= 3) {
    info.num_points = db.NumPoints();
    info.num_observations = db.NumObservations();
  }
  std::error_code error;
  info.file_bytes = static_cast<int64_t>(fs::file_size(db_path, error));
  const auto wal = fs::file_size(db_path + "-wal", error);
  if (!error) info.file_bytes += static_cast<int64_t>(wal);
  return info;
}

std::string FormatDatabaseInfo(const DatabaseInfo& info) {
  std::string text = fmt::format("database        {}\nschema version  {}\n", info.path,
                                 info.schema_version);
  if (info.enu_origin) {
    text += fmt::format("ENU origin      {:.8f} {:.8f} {:.3f} (lat deg, lon deg, alt m)\n",
                        info.enu_origin->lat_deg, info.enu_origin->lon_deg,
                        info.enu_origin->alt_m);
  }
  text += fmt::format("route length    {:.2f} m\n", info.route_length_m);
  text += fmt::format("frames          {}\n", info.num_frames);
  text += fmt::format("features/frame  min {} mean {:.0f} max {}\n", info.min_features_per_frame,
                      info.mean_features_per_frame, info.max_features_per_frame);
  text += fmt::format("3-D points      {} ({} observations, {:.2f} per point){}\n",
                      info.num_points, info.num_observations,
                      info.num_points > 0
                          ? static_cast<double>(info.num_observations) / info.num_points
                          : 0.0,
                      info.schema_version < 3 ? " (schema before 3: run epiloc triangulate)" : "");
  text += fmt::format("size            {:.1f} MB ({:.0f} kB per frame)\n", info.file_bytes / 1e6,
                      info.num_frames > 0 ? info.file_bytes / 1e3 / info.num_frames : 0.0);
  text += fmt::format("drives          {}\n", info.drives.size());
  for (const DriveInfo& d : info.drives) {
    text += fmt::format(
        // Names and sources come from drive.json files: a line break or ESC [2J in one must not
        // split the line or drive the terminal.
        "  {}: {} frames{} ({}x{}), s {:.2f}..{:.2f} m, positions from {}{}\n",
        Printable(d.name, d.name.size()),
        d.num_frames,
        d.num_frames_planned != d.num_frames ? fmt::format(" of {}", d.num_frames_planned) : "",
        d.width, d.height, d.s_min_m, d.s_max_m, Printable(d.positions, d.positions.size()),
        d.complete ? "" : ", INCOMPLETE (re-run build-db to finish)");
  }
  return text;
}

}  // namespace epiloc
