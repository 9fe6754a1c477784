#include <cstdio>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/progress.h"
#include "epiloc/survey/build_db.h"

namespace epiloc {

int RunBuildDb(int argc, char** argv) {
  CLI::App app("Add a survey drive to a route database: positions interpolated to frame times, "
               "SIFT features of the undistorted frames. Re-running adds no duplicates and "
               "resumes an interrupted build.",
               "build-db");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string drive_dir, db_path;
  BuildDbOptions options;
  app.add_option("--drive", drive_dir, "Drive directory (with drive.json)")->required();
  app.add_option("--db", db_path, "Route database (SQLite), created if missing")->required();
  app.add_option("--positions", options.positions,
                 "auto | ground_truth | gnss | a position CSV (e.g. a georeferenced trajectory)")
      ->capture_default_str();
  app.add_option("--threads", options.num_threads, "Worker threads (0 = one per core)")
      ->capture_default_str();
  app.add_option("--max-features", options.sift.max_num_features,
                 "SIFT features kept per frame, strongest first (0 = all)")
      ->capture_default_str();
  app.add_option("--max-image-size", options.sift.max_image_size,
                 "Downscale frames whose longer side exceeds this for SIFT (0 = never)")
      ->capture_default_str();
  app.add_option("--contrast-threshold", options.sift.contrast_threshold,
                 "SIFT contrast threshold")
      ->capture_default_str();
  bool no_triangulate = false;
  app.add_flag("--no-triangulate", no_triangulate,
               "Skip triangulating the local 3-D structure afterwards (run `epiloc triangulate` "
               "later for its options)");
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  const bool positions_file =
      options.positions != "auto" && options.positions != "ground_truth" &&
      options.positions != "gnss";
  CheckCommandOutputs({{"--db", db_path}},
                      {{"--drive", drive_dir}, {"--positions", positions_file ? options.positions : ""}});
  options.triangulate = !no_triangulate;

  Progress progress("build-db", 0);
  const BuildDbSummary summary = BuildDatabase(drive_dir, db_path, options, progress.Callback());
  progress.Finish();
  std::printf(
      "drive %s: %lld frames added (%lld features), %lld already present, %lld without "
      "position, %.1f s (%.1f frames/s)\n",
      summary.drive_name.c_str(), static_cast<long long>(summary.frames_added),
      static_cast<long long>(summary.features_added),
      static_cast<long long>(summary.frames_already_present),
      static_cast<long long>(summary.frames_without_position), summary.seconds,
      summary.seconds > 0 ? summary.frames_added / summary.seconds : 0.0);
  if (summary.triangulated) PrintTriangulateSummary(summary.triangulation);
  return kExitOk;
}

}  // namespace epiloc
