#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "cli_common.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/anchor/radial_calibration.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/io/drive.h"
#include "epiloc/vo/visual_odometry.h"

namespace epiloc {

int RunCalibrateRadial(int argc, char** argv) {
  CLI::App app(
      "Estimate a residual radial distortion of the drive's camera from a LiDAR map: the k1 (or "
      "k2) at which the drive's monocular VO keeps its scale along the road, as its structure "
      "anchors in the map measure it (one VO and anchoring run per tried value, secant search). "
      "Writes the drive with that camera (its frames and positions unchanged), a CSV of the "
      "runs and, with --vo-out, the best run's VO for `epiloc anchor --vo`.",
      "calibrate-radial");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  AnchorInputs inputs;
  inputs.every = 10;  // the trend wants anchors along the drive, not every frame: each run is
                      // one anchoring of the drive
  RadialCalibrationOptions options;
  std::string out_dir, vo_out, origin_text, db_path, term = "k1";
  app.add_option("--drive", inputs.drive_dir, "Drive whose camera is calibrated")->required();
  app.add_option("--cloud", inputs.cloud_path, "Map: point-cloud file or tile directory")
      ->required();
  app.add_option("--out", out_dir,
                 "Drive directory to write: the drive with the calibrated camera; the runs' "
                 "drives and radial_calibration.csv go beside, in OUT/calibration")
      ->required();
  app.add_option("--vo-out", vo_out,
                 "The best run's VO trajectory (TUM, its points beside as .points.csv)");
  app.add_option("--term", term, "The radial term estimated: k1 or k2")
      ->check(CLI::IsMember({"k1", "k2"}))
      ->capture_default_str();
  app.add_option("--every", inputs.every, "Anchor every n-th frame of the drive")
      ->capture_default_str();
  app.add_option("--cloud-origin", origin_text,
                 "LAT,LON,ALT of the cloud's ENU origin (when it has no sidecar)");
  app.add_option("--db", db_path, "Route database whose ENU origin the cloud uses (no sidecar)");
  app.add_option("--gnss-sigma", options.structure.gnss_sigma_m,
                 "Horizontal GNSS sigma, metres")
      ->capture_default_str();
  app.add_option("--camera-height", options.structure.prior.camera_height_m,
                 "Camera above the road, metres")
      ->capture_default_str();
  app.add_option("--heading-error-deg", options.structure.heading_error_deg,
                 "Testing: perturb each prior heading by a seeded uniform error in +-D degrees")
      ->capture_default_str();
  app.add_option("--seed", options.structure.seed, "Seed of the heading perturbation")
      ->capture_default_str();
  app.add_option("--tolerance", options.tolerance_percent_per_100m,
                 "Converged when the VO's scale changes by at most this, percent per 100 m")
      ->capture_default_str();
  app.add_option("--max-runs", options.max_runs, "VO and anchoring runs at most")
      ->capture_default_str();
  app.add_option("--first-step", options.first_step, "The second run's term minus the first's")
      ->capture_default_str();
  app.add_option("--max-change", options.max_change,
                 "The term moves at most this far from the drive's calibration")
      ->capture_default_str();
  app.add_option("--min-distance", options.min_distance_m,
                 "A run's ok anchors must span at least this, metres")
      ->capture_default_str();
  app.add_option("--threads", options.structure.num_threads, "Threads")->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  options.term = term == "k2" ? RadialCalibrationOptions::Term::kK2
                              : RadialCalibrationOptions::Term::kK1;
  options.vo.num_threads = options.structure.num_threads;
  options.vo.keep_points = true;
  options.sift_threads = options.structure.num_threads;
  CheckCommandOutputs({{"--out", out_dir}, {"--vo-out", vo_out}},
                      {{"--cloud", inputs.cloud_path},
                       {"--drive", inputs.drive_dir},
                       {"--db", db_path}});
  options.Check();

  MapOriginInputs origin_inputs{inputs.cloud_path, std::nullopt, db_path};
  if (!origin_text.empty()) {
    origin_inputs.explicit_origin = ParseGeodetic(origin_text, "--cloud-origin");
  }
  inputs.map_origin = ResolveMapOrigin(origin_inputs).enu_origin;

  const std::string work_dir = (std::filesystem::path(out_dir) / "calibration").string();
  const std::string table_path = (std::filesystem::path(work_dir) / "radial_calibration.csv").string();
  // The runs' table, written again after each run: an interrupted search keeps what it measured.
  std::vector<RadialCalibrationRun> runs;
  const auto write_table = [&] {
    CsvWriter csv(table_path, {"run", "term", "value", "ok_anchors", "anchors",
                               "trend_percent_per_100m", "distance_m", "first_scale", "last_scale",
                               "median_residual_m", "seconds", "message"});
    for (size_t i = 0; i < runs.size(); ++i) {
      const RadialCalibrationRun& r = runs[i];
      csv.WriteRow({std::to_string(i + 1), term, fmt::format("{:.6f}", r.term),
                    std::to_string(r.ok_anchors), std::to_string(r.anchors),
                    r.trend ? fmt::format("{:.3f}", r.trend->percent_per_100m) : "",
                    r.trend ? fmt::format("{:.1f}", r.trend->distance_m) : "",
                    r.trend ? fmt::format("{:.5f}", r.trend->first_scale) : "",
                    r.trend ? fmt::format("{:.5f}", r.trend->last_scale) : "",
                    fmt::format("{:.4f}", r.median_residual_m), fmt::format("{:.1f}", r.seconds),
                    r.message});
    }
    csv.Close();
  };
  Progress progress("calibrate-radial", options.max_runs);
  const RadialCalibrationResult result = CalibrateRadialTerm(
      inputs, options, work_dir,
      [&](const RadialCalibrationRun& run) {
        runs.push_back(run);
        write_table();
      },
      progress.Callback());
  progress.Finish();
  for (size_t i = 0; i < result.runs.size(); ++i) {
    const RadialCalibrationRun& r = result.runs[i];
    if (r.trend) {
      std::printf("run %zu: %s = %+.4f: %d of %d anchors ok, VO scale %+.1f %% per 100 m over "
                  "%.0f m, residual %.3f m, %.0f s\n",
                  i + 1, term.c_str(), r.term, r.ok_anchors, r.anchors, r.trend->percent_per_100m,
                  r.trend->distance_m, r.median_residual_m, r.seconds);
    } else {
      std::printf("run %zu: %s = %+.4f: %s, %.0f s\n", i + 1, term.c_str(), r.term,
                  r.message.c_str(), r.seconds);
    }
  }
  if (!result.converged) {
    Throw("{}: {} not calibrated: {} (runs in {}); no drive written", inputs.drive_dir, term,
          result.message, table_path);
  }
  Drive drive = LoadDrive(inputs.drive_dir);
  const double calibrated = drive.camera.distortion[RadialTermIndex(options.term)];
  drive.camera = result.camera;
  WriteDrive(drive, out_dir);
  if (!vo_out.empty()) {
    WriteVoTrajectory(result.vo, vo_out, drive.name, std::filesystem::absolute(out_dir).string());
    WriteVoPoints(result.vo.points, VoPointsPath(vo_out));
  }
  std::printf("%s: %s = %+.4f (was %+.4f), the VO's scale within %.1f %% per 100 m (%+.1f)\n",
              out_dir.c_str(), term.c_str(), result.term, calibrated,
              options.tolerance_percent_per_100m,
              result.runs[result.best_run].trend->percent_per_100m);
  return kExitOk;
}

}  // namespace epiloc
