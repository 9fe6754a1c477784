#include <algorithm>
#include <cstdio>
#include <optional>
#include <vector>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/progress.h"
#include "epiloc/synth/drive_gen.h"

namespace epiloc {
namespace {

// Appearance variants: what differs between the survey's day and the query's besides camera and
// path (values as given on the command line; applied after the other options).
struct AppearanceFlags {
  double lead_vehicle_gap_m = 0.0;
  int traffic = 0;
  double query_parked_cars_changed = 0.0;
  std::vector<double> survey_sun, query_sun;  // azimuth, elevation (degrees)
  std::optional<double> survey_exposure, query_exposure;
  std::vector<double> survey_white_balance, query_white_balance;  // r, g, b
  double vegetation = 0.0;
};

void AddAppearanceFlags(CLI::App& app, AppearanceFlags& f) {
  app.add_option("--lead-vehicle-gap-m", f.lead_vehicle_gap_m,
                 "A lead vehicle, the same car in both drives, this far ahead of the camera "
                 "(metres along the road to its back, 4-40; varies slowly and differently per "
                 "drive, +-25 %); 0 = none")
      ->capture_default_str();
  app.add_option("--traffic", f.traffic,
                 "Moving cars per drive, other ones in each drive (2/3 oncoming in the other "
                 "lane, 1/3 ahead driving away)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  app.add_option("--query-parked-cars-changed", f.query_parked_cars_changed,
                 "Share of parking slots whose car is removed, added or replaced in the query's "
                 "world (the worlds differ only by these cars)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--survey-sun", f.survey_sun,
                 "Sun of the survey drive: AZ,EL degrees (azimuth clockwise from north, "
                 "elevation 10-90): shading and cast shadows; none = unshaded")
      ->delimiter(',')
      ->expected(2);
  app.add_option("--query-sun", f.query_sun, "Sun of the query drive: AZ,EL degrees (see above)")
      ->delimiter(',')
      ->expected(2);
  app.add_option("--survey-exposure", f.survey_exposure,
                 "Exposure gain of the survey frames (default 1)");
  app.add_option("--query-exposure", f.query_exposure,
                 "Exposure gain of the query frames (default 0.85)");
  app.add_option("--survey-white-balance", f.survey_white_balance,
                 "White balance of the survey frames: R,G,B channel gains (default 1,1,1)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--query-white-balance", f.query_white_balance,
                 "White balance of the query frames: R,G,B channel gains (default 1,1,1)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--vegetation", f.vegetation,
                 "Share of the road's length with hedges and rows of identical trees "
                 "(repetitive foliage), on each side; part of the world")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
}

void ApplyAppearanceFlags(const AppearanceFlags& f, SynthOptions& options) {
  AppearanceOptions& a = options.appearance;
  a.moving.lead_vehicle_gap_m = f.lead_vehicle_gap_m;
  a.moving.traffic = f.traffic;
  a.query_parked_cars_changed = f.query_parked_cars_changed;
  const auto sun = [](const std::vector<double>& v) -> std::optional<SunOptions> {
    if (v.empty()) return std::nullopt;
    SunOptions s;
    s.azimuth_deg = v[0];
    s.elevation_deg = v[1];
    return s;
  };
  a.survey_sun = sun(f.survey_sun);
  a.query_sun = sun(f.query_sun);
  if (f.survey_exposure) options.survey.render.exposure_gain = *f.survey_exposure;
  if (f.query_exposure) options.query.render.exposure_gain = *f.query_exposure;
  const auto white_balance = [](const std::vector<double>& v, RenderOptions& render) {
    if (!v.empty()) render.white_balance_rgb = {v[0], v[1], v[2]};
  };
  white_balance(f.survey_white_balance, options.survey.render);
  white_balance(f.query_white_balance, options.query.render);
  options.world.vegetation.fraction = f.vegetation;
}

}  // namespace

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
  AppearanceFlags appearance;
  AddAppearanceFlags(app, appearance);
  if (auto code = Parse(app, flags, argc, argv)) return *code;

  options.lidar = !no_lidar;
  if (query_length_m > 0) {
    options.query.end_offset_m =
        std::max(options.query.end_offset_m,
                 options.length_m - options.query.start_offset_m - query_length_m);
  }
  if (no_distortion) options.query.camera.distortion.fill(0.0);
  if (clean_query) {
    options.query.render = options.survey.render;
    options.query.exposure_s = 0.0;
    options.query.wobble_yaw_deg = 0.0;
    options.query.wobble_pitch_deg = 0.0;
  }
  ApplyAppearanceFlags(appearance, options);
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
