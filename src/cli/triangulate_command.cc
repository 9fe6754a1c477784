#include <cstdio>
#include <filesystem>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/db/database.h"
#include "epiloc/survey/triangulate.h"

namespace epiloc {

void PrintTriangulateSummary(const TriangulateSummary& s) {
  std::printf(
      "triangulation: %lld points, %lld observations (mean track length %.2f, mean reprojection "
      "error %.2f px) from %lld frames of %lld drives (%lld without orientation skipped), %lld "
      "pairs, %lld matches, %lld epipolar inliers, %lld tracks, %.1f s\n",
      static_cast<long long>(s.num_points), static_cast<long long>(s.num_observations),
      s.mean_track_length, s.mean_error_px, static_cast<long long>(s.num_frames),
      static_cast<long long>(s.num_drives), static_cast<long long>(s.frames_without_orientation),
      static_cast<long long>(s.num_pairs), static_cast<long long>(s.num_matches),
      static_cast<long long>(s.num_epipolar_inliers), static_cast<long long>(s.num_tracks),
      s.seconds);
}

int RunTriangulate(int argc, char** argv) {
  CLI::App app(
      "Triangulate the local 3-D structure of a route database: features matched "
      "between neighbouring frames of each drive with known poses, checked against the "
      "epipolar geometry, joined into tracks and triangulated multi-view. Replaces the "
      "stored points; the database is migrated to the latest schema first.",
      "triangulate");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string db_path;
  TriangulateOptions options;
  app.add_option("--db", db_path, "Route database (SQLite), built by build-db")->required();
  app.add_option("--neighbours", options.num_neighbours,
                 "Following frames each frame is matched with")
      ->capture_default_str();
  app.add_option("--min-baseline", options.min_baseline_m,
                 "Neighbours closer than this are passed over, metres")
      ->capture_default_str();
  app.add_option("--max-baseline", options.max_baseline_m, "Farthest neighbour, metres")
      ->capture_default_str();
  app.add_option("--max-features", options.max_features,
                 "Strongest features per frame that are matched (0 = all)")
      ->capture_default_str();
  app.add_option("--ratio", options.matching.ratio, "Lowe's ratio test")->capture_default_str();
  app.add_option("--num-checks", options.matching.num_checks,
                 "FLANN leaves visited per search (more: slower, closer to exact)")
      ->capture_default_str();
  app.add_option("--max-epipolar-error", options.max_epipolar_error_px,
                 "Largest distance of a match from its epipolar line, pixels")
      ->capture_default_str();
  app.add_option("--max-reprojection-error", options.max_reprojection_error_px,
                 "Largest reprojection error of a kept observation, pixels")
      ->capture_default_str();
  app.add_option("--min-angle", options.min_triangulation_angle_deg,
                 "Smallest largest angle between a point's rays, degrees")
      ->capture_default_str();
  app.add_option("--min-depth", options.min_depth_m, "Nearest point depth, metres")
      ->capture_default_str();
  app.add_option("--max-depth", options.max_depth_m, "Farthest point depth, metres")
      ->capture_default_str();
  app.add_option("--min-observations", options.min_observations,
                 "Observations a point needs (>= 2)")
      ->capture_default_str();
  app.add_option("--threads", options.num_threads, "Worker threads (0 = one per core)")
      ->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;

  options.Check();
  if (!std::filesystem::exists(db_path)) Throw("{}: no such database", db_path);
  Database db(db_path);
  Progress progress("triangulate", 0);
  const TriangulateSummary summary = TriangulateDatabase(db, options, progress.Callback());
  progress.Finish();
  PrintTriangulateSummary(summary);
  return kExitOk;
}

}  // namespace epiloc
