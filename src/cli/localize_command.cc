#include <cstdio>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/eval/export.h"
#include "epiloc/localize/localizer.h"

namespace epiloc {

int RunLocalize(int argc, char** argv) {
  CLI::App app(
      "Localize every frame of a drive along the route of a database: epipolar distance to "
      "database frames, DTW alignment and V-fit (Kyutoku et al.). Writes the result CSV that "
      "`epiloc evaluate` reads.",
      "localize");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string db_path, drive_dir, out_path, geojson_path, diagnostics_path, mode = "online";
  LocalizeOptions options;
  bool no_gps = false;
  app.add_option("--db", db_path, "Route database (SQLite)")->required();
  app.add_option("--drive", drive_dir, "Drive directory to localize")->required();
  app.add_option("--out", out_path, "Result CSV")->required();
  app.add_option("--mode", mode, "fixed (both ends aligned), free (end free) or online (causal)")
      ->check(CLI::IsMember({"fixed", "free", "online"}))
      ->capture_default_str();
  app.add_flag("--no-gps", no_gps, "Do not use the drive's GNSS (image retrieval places it)");
  app.add_flag("--all-methods", options.all_methods,
               "Write gps, nearest, dtw_fixed, fit_fixed, dtw_free, fit_free and online rows");
  app.add_option("--geojson", geojson_path, "Also write the estimates as GeoJSON");
  app.add_option("--diagnostics", diagnostics_path,
                 "Per-pair diagnostics CSV (d values, inliers, fit residuals)");
  app.add_option("--threads", options.num_threads, "Threads (0 = one per core)")
      ->capture_default_str();
  app.add_option("--gps-window-m", options.gps_window_m,
                 "Search half-width around the GPS prior when (re)initialising")
      ->capture_default_str();
  app.add_option("--track-window-m", options.track_window_m,
                 "Half-width of the database window evaluated around the predicted position")
      ->capture_default_str();
  app.add_option("--fit-window-m", options.fit_window_m,
                 "Database frames within this of the DTW match enter the V-fit")
      ->capture_default_str();
  app.add_option("--max-query-features", options.max_query_features,
                 "Strongest SIFT features of a query frame")
      ->capture_default_str();
  app.add_option("--query-max-image-size", options.sift.max_image_size,
                 "Query frames whose longer side exceeds this are downscaled for SIFT (0 = never)")
      ->capture_default_str();
  app.add_option("--query-upsampled-octave", options.sift.upsampled_octave,
                 "Query SIFT also detects in the upsampled octave (finest features, ~2.5x the "
                 "extraction time)")
      ->capture_default_str();
  std::string robust = "fast";
  app.add_option("--ransac", robust,
                 "Robust essential-matrix estimator per pair: fast (USAC LO-RANSAC) or magsac "
                 "(MAGSAC++, slower)")
      ->check(CLI::IsMember({"fast", "magsac"}))
      ->capture_default_str();
  std::string matcher = "window";
  app.add_option("--matcher", matcher,
                 "window: one FLANN search per query frame over its database window; pairs: one "
                 "search per query/database pair (slower, reference)")
      ->check(CLI::IsMember({"window", "pairs"}))
      ->capture_default_str();
  app.add_option("--match-checks", options.pairs.match.num_checks,
                 "FLANN leaves visited per descriptor search (speed / recall)")
      ->capture_default_str();
  app.add_option("--max-db-features", options.pairs.max_db_features,
                 "Strongest database features per frame")
      ->capture_default_str();
  app.add_option("--dtw-max-step", options.dtw.max_step,
                 "Most database frames a query frame may advance")
      ->capture_default_str();
  std::string refine = "pnp";
  app.add_option("--refine", refine,
                 "pnp: 6-DoF pose against the survey's 3-D points (pnp rows; needs a triangulated "
                 "database) | none")
      ->capture_default_str();
  app.add_option("--refine-max-disagreement-m", options.refine.max_along_disagreement_m,
                 "PnP poses farther along the route from the epipolar estimate are rejected")
      ->capture_default_str();
  app.add_option("--refine-max-error-px", options.refine.pnp.max_reprojection_px,
                 "PnP RANSAC inlier threshold of the refinement, pixels")
      ->capture_default_str();
  app.add_option("--refine-min-inliers", options.refine.min_inliers,
                 "Fewer PnP inliers: the epipolar estimate is kept (flagged thin)")
      ->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  if (refine != "pnp" && refine != "none") epiloc::Throw("--refine '{}': expected pnp or none", refine);
  options.refine.enabled = refine == "pnp";
  options.mode = ParseMode(mode);
  options.use_gps = !no_gps;
  options.pairs.window_matching = matcher == "window";
  options.pairs.epipole.robust =
      robust == "fast" ? EpipoleOptions::Robust::kFast : EpipoleOptions::Robust::kMagsac;

  Progress progress("localize", 0);
  const LocalizeRun run = Localize(db_path, drive_dir, options, progress.Callback());
  progress.Finish();
  WriteResultCsv(run.results, out_path);
  if (!geojson_path.empty()) {
    ExportOptions geojson;
    geojson.format = TrajectoryFormat::kGeoJson;
    ExportTrajectory(run.results, geojson, geojson_path);
  }
  if (!diagnostics_path.empty()) WriteDiagnosticsCsv(run, diagnostics_path);
  std::printf(
      "%s: %d frames, %d localized online, %d (re)initialisations, %lld pairs, %.1f s "
      "(%.1f frames/s)\n",
      out_path.c_str(), run.num_frames, run.num_localized_online, run.num_reinitialisations,
      static_cast<long long>(run.num_pairs), run.seconds, run.frames_per_second);
  if (run.refined) {
    std::printf("%s: 6-DoF refinement: %d frames refined, %d thin structure, %d rejected "
                "(epipolar estimate kept, flagged)\n",
                out_path.c_str(), run.num_refined_ok, run.num_refine_thin,
                run.num_refine_rejected);
  }
  return kExitOk;
}

}  // namespace epiloc
