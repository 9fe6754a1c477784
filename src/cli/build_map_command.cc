#include <cstdio>
#include <string>

#include <spdlog/spdlog.h>

#include "cli_common.h"
#include "epiloc/anchor/build_map.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/io/drive.h"

namespace epiloc {

int RunBuildMap(int argc, char** argv) {
  CLI::App app(
      "Merge a drive's LiDAR scans (lidar.csv poses) into one voxel-filtered point cloud in a "
      "local ENU frame, optionally coloured from the drive's camera frames (occlusion-aware). "
      "The frame is written to the sidecar <out>.json, which render and anchor read.",
      "build-map");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string drive_dir, out_path, db_path, origin_text, colour_mode = "closest";
  BuildMapOptions options;
  app.add_option("--drive", drive_dir, "Drive directory with LiDAR scans (drive.json 'lidar')")
      ->required();
  app.add_option("--out", out_path, "Map file to write (.ply recommended; also .pcd, .xyz)")
      ->required();
  app.add_option("--voxel", options.voxel_m, "Voxel side of the filter, metres (0 = none)")
      ->capture_default_str();
  app.add_flag("--colorize", options.colorize,
               "Colour the points from the drive's camera frames (needs camera orientations)");
  app.add_option("--colour-mode", colour_mode,
                 "closest: colour of the nearest frame that sees the point; average: mean over "
                 "all frames that see it")
      ->capture_default_str();
  app.add_option("--colour-step", options.colour.frame_step, "Colour from every n-th frame")
      ->capture_default_str();
  app.add_option("--colour-range", options.colour.max_range_m,
                 "A frame colours points at most this far away, metres")
      ->capture_default_str();
  app.add_option("--colour-min-range", options.colour.min_range_m,
                 "A frame colours points at least this far away, metres")
      ->capture_default_str();
  app.add_flag("--keep-uncoloured", options.colour.keep_uncoloured,
               "Keep points no frame sees (grey) instead of dropping them");
  app.add_option("--db", db_path, "Route database whose ENU origin the map uses");
  app.add_option("--origin", origin_text,
                 "LAT,LON,ALT of the map's ENU origin (default: --db's, else the drive's first "
                 "position)");
  AddScanRangeOptions(app, options.min_range_m, options.max_range_m);
  std::string spin = "cw";
  app.add_option("--deskew-period", options.deskew_period_s,
                 "Motion-compensate spinning-LiDAR scans with this revolution period, seconds (0 "
                 "= off; KITTI HDL-64E: 0.1); needs the drive's camera orientations")
      ->capture_default_str();
  app.add_option("--spin", spin, "Spin direction seen from above: cw | ccw")->capture_default_str();
  app.add_option("--threads", options.num_threads, "Worker threads")->capture_default_str();
  bool check_scale = false;
  app.add_flag("--check-track-scale", check_scale,
               "Also merge the scans with the track stretched by 0.94-1.06 and report the "
               "stretch with which the scans agree best (a track with slow position errors draws "
               "shared surfaces twice, thicker); the map written is unstretched");
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  // The origin sidecar <out>.json is written too: it must not be an input either.
  CheckCommandOutputs({{"--out", out_path}, {"--out (sidecar)", SidecarPath(out_path)}},
                      {{"--drive", drive_dir}, {"--db", db_path}});
  if (!db_path.empty() && !origin_text.empty()) Throw("give --db or --origin, not both");
  options.colour.mode = ParseColourMode(colour_mode);
  if (spin != "cw" && spin != "ccw") Throw("--spin '{}': expected cw or ccw", spin);
  options.spin_clockwise = spin == "cw";

  std::optional<Geodetic> origin;
  std::string origin_source;
  if (!origin_text.empty()) {
    origin = ParseGeodetic(origin_text, "--origin");
    origin_source = "given (--origin)";
  } else if (!db_path.empty()) {
    origin = DatabaseEnuOrigin(db_path);
    origin_source = "database " + db_path;
  }
  if (check_scale) {
    const Drive drive = LoadDrive(drive_dir);
    if (drive.lidar.empty()) {
      Throw("{}: the drive has no LiDAR scans (drive.json 'lidar')", drive_dir);
    }
    const Geodetic check_origin =
        origin ? *origin : drive.lidar.front().sensor_position;  // any: a translation
    const TrackScaleCheck c = CheckTrackScale(drive, EnuFrame(check_origin), options);
    std::printf("track scale check: %lld scans over %.1f m, %lld points, %.2f m cells\n",
                static_cast<long long>(c.num_scans), c.span_m, static_cast<long long>(c.num_points),
                c.voxel_m);
    for (size_t i = 0; i < c.factors.size(); ++i) {
      std::printf("  stretch %.3f: shared surfaces %.4f m thick (%lld cells)\n", c.factors[i],
                  c.thickness_m[i], static_cast<long long>(c.shared_voxels[i]));
    }
    const double change_m = (c.best_factor - 1.0) * c.span_m;
    std::printf(
        "track scale check: the scans agree best with the track stretched by %.3f (%+.2f m "
        "over its %.1f m)\n",
        c.best_factor, change_m, c.span_m);
    // Twice the check's step: one step is its resolution.
    if (std::abs(c.best_factor - 1.0) >= 0.01) {
      spdlog::warn(
          "{}: the track's positions and its LiDAR disagree by {:+.1f} % of distance: maps, "
          "databases and ground truth from this track inherit it",
          drive_dir, 100.0 * (c.best_factor - 1.0));
    }
  }
  Progress progress("build-map", 0);
  const BuildMapSummary s =
      BuildMap(drive_dir, out_path, origin, origin_source, options, progress.Callback());
  progress.Finish();
  std::printf(
      "%s: %lld points from %lld scans (%lld scan points), voxel %.3f m%s; origin %.9f,%.9f,%.3f; "
      "sidecar %s; %.1f s\n",
      out_path.c_str(), static_cast<long long>(s.num_points_out),
      static_cast<long long>(s.num_scans), static_cast<long long>(s.num_points_in),
      options.voxel_m,
      options.colorize
          ? fmt::format(", {} coloured from {} frames ({}), {} unseen dropped",
                        s.num_coloured_points, s.num_colour_frames, colour_mode,
                        s.num_dropped_uncoloured)
                .c_str()
          : "",
      s.enu_origin.lat_deg, s.enu_origin.lon_deg, s.enu_origin.alt_m,
      SidecarPath(out_path).c_str(), s.seconds);
  return kExitOk;
}

}  // namespace epiloc
