#include <cstdio>
#include <string>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/io/drive.h"
#include "epiloc/vo/visual_odometry.h"

namespace epiloc {

int RunVo(int argc, char** argv) {
  CLI::App app(
      "Monocular visual odometry of a drive's frames: KLT tracks, essential-matrix "
      "initialisation, PnP tracking, keyframes and local bundle adjustment. Writes the camera "
      "trajectory as TUM (relative frame and scale; segments after a tracking loss are joined, "
      "see '# segment' lines) for `epiloc georef`.",
      "vo");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string drive_dir, out_path, points_path;
  VoOptions options;
  app.add_option("--drive", drive_dir, "Drive directory")->required();
  app.add_option("--out", out_path, "TUM trajectory to write")->required();
  app.add_option("--points", points_path,
                 "CSV of the map's 3-D points (default: --out with the extension .points.csv; "
                 "'none' = not written), for `epiloc anchor --method structure`");
  app.add_option("--max-features", options.klt.max_features, "Tracked features per frame")
      ->capture_default_str();
  // The tracker's settings: the anchors from the VO's points depend on them (README, "How much
  // the anchors depend on the VO's tracker"); the anchoring suite varies them.
  app.add_option("--klt-window", options.klt.window_px,
                 "Side of the Lucas-Kanade window, pixels (odd, >= 5)")
      ->capture_default_str();
  app.add_option("--klt-quality", options.klt.quality_level,
                 "Corners kept: Shi-Tomasi response relative to the image's best corner, (0, 1)")
      ->capture_default_str();
  app.add_option("--klt-fb-error", options.klt.max_fb_error_px,
                 "Tracks dropped above this forward-backward error, pixels")
      ->capture_default_str();
  app.add_option("--klt-min-distance", options.klt.min_distance_px,
                 "Least distance between two tracked features, pixels")
      ->capture_default_str();
  app.add_option("--init-min-flow-px", options.init_min_flow_px,
                 "Median feature motion (pixels) before the map is initialised")
      ->capture_default_str();
  app.add_option("--max-error-px", options.max_error_px,
                 "Inlier threshold of tracking, triangulation and BA (pixels)")
      ->capture_default_str();
  app.add_option("--min-inliers", options.min_inliers,
                 "Fewer 2D-3D inliers in a frame means tracking is lost")
      ->capture_default_str();
  app.add_option("--keyframe-baseline-ratio", options.keyframe_baseline_ratio,
                 "New keyframe when the baseline reaches this share of the scene depth")
      ->capture_default_str();
  app.add_option("--ba-window", options.ba_window, "Keyframes in the local bundle adjustment")
      ->capture_default_str();
  app.add_option("--global-ba-iterations", options.global_ba_iterations,
                 "Iterations of the final bundle adjustment over all keyframes (0 = none)")
      ->capture_default_str();
  app.add_option("--threads", options.num_threads, "Bundle-adjustment threads")
      ->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  options.keep_points = points_path != "none";
  if (options.keep_points && points_path.empty()) points_path = VoPointsPath(out_path);
  // --points is an output too: `--points <drive>/frames.csv` overwrote the drive's frames CSV.
  CheckCommandOutputs({{"--out", out_path}, {"--points", options.keep_points ? points_path : ""}},
                      {{"--drive", drive_dir}});

  options.Check();
  const Drive drive = LoadDrive(drive_dir);
  Progress progress("vo", static_cast<int64_t>(drive.frames.size()));
  const VoResult result = RunVisualOdometry(drive, options, progress.Callback());
  progress.Finish();
  // An empty (or one-pose) trajectory is no result: `epiloc georef` cannot use it.
  if (result.poses.size() < 2) {
    Throw(
        "{}: drive '{}': {} of {} frames could be posed (too few frames, or too little texture "
        "to track); nothing written",
        drive.dir, drive.name, result.poses.size(), drive.frames.size());
  }
  WriteVoTrajectory(result, out_path, drive.name, drive.dir);
  if (options.keep_points) {
    WriteVoPoints(result.points, points_path);
    std::printf("%s: %zu map points\n", points_path.c_str(), result.points.size());
  }
  const VoSummary& s = result.summary;
  std::printf(
      "%s: %lld of %lld frames posed, %lld keyframes, %zu segment(s), %lld tracking loss(es), "
      "%.1f inliers per frame, %.1f frames/s (bundle adjustment %.1f s of %.1f s, the final "
      "global one %.1f s)\n",
      out_path.c_str(), static_cast<long long>(s.posed), static_cast<long long>(s.frames),
      static_cast<long long>(s.keyframes), result.segments.size(), static_cast<long long>(s.lost),
      s.mean_inliers, s.frames_per_s(), s.ba_seconds, s.seconds, s.global_ba_seconds);
  return kExitOk;
}

}  // namespace epiloc
