#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/georef/anchors.h"
#include "epiloc/georef/georef.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/stella_map.h"

namespace epiloc {

int RunGeoref(int argc, char** argv) {
  CLI::App app(
      "Georeference a monocular trajectory (epiloc vo, ORB-SLAM2/3, stella_vslam: TUM or KITTI "
      "poses) with anchors (status ok rows of a result CSV, e.g. from `epiloc anchor`): paper "
      "(Kurobe et al. eq. 3-7), sim3 (Umeyama over all anchors) or piecewise (re-anchored between "
      "consecutive anchors). Writes a result CSV with orientation per frame. With "
      "--simulate-anchors, writes anchors made from the drive's ground truth instead.",
      "georef");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string vo_path, anchors_path, out_path, drive_dir, methods = "piecewise", vo_format = "auto";
  TrajectoryImportOptions import;
  GeorefOptions options;
  std::string anchor_method = "anchor";
  bool simulate = false;
  AnchorSimulationOptions simulation;
  app.add_option("--vo", vo_path, "Monocular trajectory: TUM or KITTI poses");
  app.add_option("--anchors", anchors_path, "Result CSV with the anchor rows");
  app.add_option("--out", out_path, "Result CSV to write")->required();
  app.add_option("--method", methods, "paper, sim3, piecewise, a comma-separated list, or all")
      ->capture_default_str();
  app.add_option("--drive", drive_dir,
                 "Drive directory: one output row per frame (else one per VO pose); frame times "
                 "for KITTI poses without --vo-times and for --relative-times");
  AddTrajectoryImportOptions(app, import, vo_format);
  app.add_option("--max-gap-s", options.max_gap_s,
                 "Longest gap between trajectory poses that is interpolated")
      ->capture_default_str();
  app.add_option("--paper-second-anchor", options.paper_second_anchor,
                 "paper: index of the scale anchor among the usable ones (-1 = last)")
      ->capture_default_str();
  app.add_option("--min-anchor-spacing-m", options.min_anchor_spacing_m,
                 "piecewise: anchors closer than this to the previous one are skipped")
      ->capture_default_str();
  app.add_option(
         "--end-drift-reach-m", options.end_drift_reach_m,
         "piecewise: beyond the end anchors the VO's scale drifts as their fits found "
         "(column scale_drift_per_m) for this many metres, then is held (0: held; the anchors' "
         "window is 40 m: 20 follows a drift as far as it was measured)")
      ->capture_default_str();
  app.add_option("--anchor-method", anchor_method, "Method of the anchor rows in --anchors")
      ->capture_default_str();
  app.add_flag("--simulate-anchors", simulate,
               "Write anchors from the ground truth of --drive (with noise) to --out instead");
  app.add_option("--anchor-step", simulation.step, "Simulation: frames between anchors")
      ->capture_default_str();
  app.add_option("--anchor-first", simulation.first, "Simulation: index of the first anchor")
      ->capture_default_str();
  app.add_option("--anchor-noise-m", simulation.position_sigma_m,
                 "Simulation: position error, 1-sigma per axis, metres")
      ->capture_default_str();
  app.add_option("--anchor-noise-deg", simulation.rotation_sigma_deg,
                 "Simulation: rotation error, 1-sigma per axis, degrees")
      ->capture_default_str();
  app.add_option("--seed", simulation.seed, "Simulation: random seed")->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  CheckCommandOutputs({{"--out", out_path}},
                      {{"--vo", vo_path},
                       {"--anchors", anchors_path},
                       {"--drive", drive_dir},
                       {"--vo-times", import.times_path}});

  if (simulate) {
    EPILOC_CHECK(!drive_dir.empty(), "--simulate-anchors needs --drive");
    const ResultTable anchors = SimulateAnchors(LoadDrive(drive_dir), simulation);
    WriteResultCsv(anchors, out_path);
    std::printf("%s: %zu simulated anchors (every %lld frames, %.3g m / %.3g deg noise)\n",
                out_path.c_str(), anchors.rows.size(), static_cast<long long>(simulation.step),
                simulation.position_sigma_m, simulation.rotation_sigma_deg);
    return kExitOk;
  }
  EPILOC_CHECK(!vo_path.empty(), "georef needs --vo (or --simulate-anchors)");
  EPILOC_CHECK(!anchors_path.empty(), "georef needs --anchors");
  options.methods = ParseGeorefMethods(methods);
  import.format = ParseTrajectoryFileFormat(vo_format);
  options.Check();
  std::vector<GeorefFrame> frames;
  if (!drive_dir.empty()) {
    const Drive drive = LoadDrive(drive_dir);
    for (const FrameRecord& f : drive.frames) frames.push_back({f.frame, f.timestamp_s});
    SetDriveFrames(drive, &import);
  } else if (import.format == TrajectoryFileFormat::kTum ||
             (import.format == TrajectoryFileFormat::kAuto && !IsMessagePackFile(vo_path))) {
    // One row per VO pose; `epiloc vo` names its drive, whose frame numbers the rows then carry.
    const std::string named = TrajectoryDriveDir(vo_path);
    if (!named.empty() && std::filesystem::is_directory(named)) {
      SetDriveFrames(LoadDrive(named), &import);
    } else if (!named.empty()) {
      spdlog::warn("{}: its drive {} is not there: rows without frame numbers (give --drive)",
                   vo_path, named);
    }
  }
  const ImportedTrajectory trajectory = ImportTrajectory(vo_path, import);
  const AnchorSet anchors = ReadAnchors(anchors_path, anchor_method);
  const GeorefResult result = Georeference(trajectory, anchors, frames, options);
  WriteResultCsv(result.table, out_path);
  std::printf(
      "%s: %zu trajectory poses, %lld of %lld ok anchors associated (%lld not ok)\n",
      out_path.c_str(), trajectory.poses.size(), static_cast<long long>(result.anchors_associated),
      static_cast<long long>(result.anchors_ok), static_cast<long long>(anchors.rows_not_ok));
  for (const GeorefMethodSummary& m : result.methods) {
    std::printf(
        "  %-9s %3d anchors used, scale %.4g..%.4g m/unit, residual at anchors rms %.3f m max "
        "%.3f m, %lld rows ok, %lld without a pose\n",
        GeorefMethodName(m.method).c_str(), m.anchors_used, m.min_scale, m.max_scale,
        m.anchor_rms_m, m.anchor_max_m, static_cast<long long>(m.rows_ok),
        static_cast<long long>(m.rows_lost));
  }
  return kExitOk;
}

}  // namespace epiloc
