#include <algorithm>
#include <cstdio>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/progress.h"
#include "epiloc/synth/drive_gen.h"

namespace epiloc {

int RunSynth(int argc, char** argv) {
  CLI::App app(
      "Generate a synthetic street with exact ground truth: a survey drive and a query drive "
      "(frames, GNSS, ground truth, calibration) in the drive format, a LiDAR map (PLY), the "
      "world description and a top view.",
      "synth");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string out_dir;
  SynthOptions options;
  bool no_lidar = false, no_distortion = false, clean_query = false;
  app.add_option("--out", out_dir, "Output directory")->required();
  app.add_option("--length-m", options.length_m, "Driven length of the survey, metres")
      ->capture_default_str();
  app.add_option("--seed", options.seed, "Seed of the world, noise and GNSS")
      ->capture_default_str();
  app.add_option("--survey-speed-mps", options.survey.speed_mps, "Survey cruising speed")
      ->capture_default_str();
  app.add_option("--survey-rate-hz", options.survey.frame_rate_hz, "Survey frame rate")
      ->capture_default_str();
  app.add_option("--query-speed-mps", options.query.speed_mps, "Query cruising speed")
      ->capture_default_str();
  app.add_option("--query-rate-hz", options.query.frame_rate_hz, "Query frame rate")
      ->capture_default_str();
  app.add_option("--query-offset-m", options.query.lateral_offset_m,
                 "Query lateral offset from the lane centre, positive to the left")
      ->capture_default_str();
  app.add_option("--gps-noise", options.query.gnss.sigma_m,
                 "Query GNSS error, 1-sigma per horizontal axis, metres")
      ->capture_default_str();
  app.add_flag("--no-distortion", no_distortion, "Query camera without lens distortion");
  app.add_flag("--clean-query", clean_query,
               "Query frames without noise, blur, exposure change or wobble");
  double query_length_m = 0.0;
  app.add_option("--query-length-m", query_length_m,
                 "Query drives only this far from its start (0 = to 10 m before the route's end)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("--no-lidar", no_lidar, "Skip the LiDAR map");
  app.add_option("--threads", options.num_threads, "Rendering threads")->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;

  options.lidar = !no_lidar;
  if (query_length_m > 0) {
    options.query.end_offset_m = std::max(
        options.query.end_offset_m,
        options.length_m - options.query.start_offset_m - query_length_m);
  }
  if (no_distortion) options.query.camera.distortion.fill(0.0);
  if (clean_query) {
    options.query.render = options.survey.render;
    options.query.exposure_s = 0.0;
    options.query.wobble_yaw_deg = 0.0;
    options.query.wobble_pitch_deg = 0.0;
  }
  Progress progress("synth", 0);
  const SynthSummary summary = GenerateSynthetic(options, out_dir, progress.Callback());
  progress.Finish();
  std::printf(
      "%s: survey %d frames, query %d frames, %d surfaces, %d LiDAR scans (%lld points), "
      "%.1f s\n",
      out_dir.c_str(), summary.num_survey_frames, summary.num_query_frames, summary.num_surfaces,
      summary.num_lidar_scans, static_cast<long long>(summary.num_lidar_points), summary.seconds);
  return kExitOk;
}

}  // namespace epiloc
