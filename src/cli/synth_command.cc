#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_common.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/cli/commands.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/synth/camera_presets.h"
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

// Query variants (issue 14): another camera, a speed profile, a turn in from a side street,
// curves on another line, a street with sharper curves.
struct VariantFlags {
  std::string camera, size, distortion, stops, sections;
  double hfov_deg = 0.0, stop_at_end_s = -1.0, turn_in_deg = 0.0;
  bool sharp_curves = false;
  bool rate_given = false;    // --query-rate-hz given: it wins over the camera preset's rate
  bool motion_given = false;  // a speed profile option given: constant acceleration per step
  double exposure_s = 0.0;    // --query-exposure-s as parsed
};

void AddVariantOptions(CLI::App& app, VariantFlags& v, SynthOptions& o) {
  app.add_option("--query-camera", v.camera,
                 "Query camera preset: default (640x360, 15 Hz), dashcam1080 (1920x1080 wide "
                 "angle, 30 Hz), vga (640x480, 15 Hz)")
      ->check(CLI::IsMember(QueryCameraPresets()));
  app.add_option("--query-size", v.size,
                 "Query image size WxH (principal point centred, focal length scaled with the "
                 "width)");
  app.add_option("--query-hfov-deg", v.hfov_deg,
                 "Query horizontal field of view, degrees (sets the focal length, distortion "
                 "included)");
  app.add_option("--query-distortion", v.distortion,
                 "Query lens distortion k1,k2,p1,p2,k3 (OpenCV; missing values are 0)");
  app.add_option("--query-jpeg-quality", o.query.jpeg_quality,
                 "Store the query frames as JPEG of this quality (1-100; 0 = PNG)")
      ->check(CLI::Range(0, 100));
  app.add_option("--query-exposure-s", o.query.exposure_s,
                 "Query exposure time: motion blur over it (0 = sharp)")
      ->capture_default_str();
  app.add_flag("--query-grey", o.query.grey, "Query frames as single-channel grey images");
  app.add_option("--query-stops", v.stops,
                 "Query stops AT:SECONDS,... replacing the default stop; AT is a fraction of the "
                 "drive (0.3) or metres from its start (40m); 'none' for no stop. Frames while "
                 "standing are identical");
  app.add_option("--query-speed-sections", v.sections,
                 "Query speed sections FROM:TO:MPS,... (fractions of the drive) replacing the "
                 "default 10 m/s section; 'none' for none");
  app.add_flag("--query-start-from-rest", o.query.start_from_rest,
               "Query starts standing and accelerates at --query-max-accel-mps2");
  app.add_option("--query-stop-at-end", v.stop_at_end_s,
                 "Query brakes to a stop at its end and stands this many seconds");
  app.add_option("--query-creep-mps", o.query.creep_mps,
                 "Query creeps at this speed over its first --query-creep-m (0 = no creeping)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--query-creep-m", o.query.creep_m, "Length of the creeping stretch, metres")
      ->capture_default_str();
  app.add_option("--query-max-accel-mps2", o.query.max_accel_mps2,
                 "Query acceleration and braking limit, m/s^2")
      ->capture_default_str();
  app.add_option("--query-start-offset-m", o.query.start_offset_m,
                 "Query starts this far after the survey's start (negative: before it, down to "
                 "the world's 30 m margin)")
      ->capture_default_str();
  app.add_option("--query-end-offset-m", o.query.end_offset_m,
                 "Query ends this far before the survey's end (negative: after it, up to 60 m)")
      ->capture_default_str();
  app.add_option("--query-turn-in-deg", v.turn_in_deg,
                 "Query starts on a side street (added to the world) and turns right into the "
                 "street by this angle (60-120 deg)");
  app.add_option("--query-turn-radius-m", o.query.turn_radius_m,
                 "Radius of the query's turn in, metres (5-15)")
      ->capture_default_str();
  app.add_option("--side-street-at-m", o.world.side_street.at_m,
                 "Wanted junction of the side street along the street (the nearest place on a "
                 "long enough straight is taken)")
      ->capture_default_str();
  app.add_option("--query-line-m", o.query.curve_cut_m,
                 "Query cuts the inside of every curve by up to this much, metres (0-2)")
      ->capture_default_str();
  app.add_flag("--sharp-curves", v.sharp_curves,
               "World with more and sharper curves: radius 25-60 m, turns up to 90 deg, "
               "straights 20-50 m");
}

// "A:B,..." -> rows of numbers; "none" -> no rows.
std::vector<std::vector<std::string>> SplitList(const std::string& text, const char* option) {
  std::vector<std::vector<std::string>> rows;
  if (text == "none") return rows;
  std::stringstream items(text);
  for (std::string item; std::getline(items, item, ',');) {
    std::vector<std::string> fields;
    std::stringstream parts(item);
    for (std::string field; std::getline(parts, field, ':');) fields.push_back(field);
    EPILOC_CHECK(!fields.empty(), "{}: empty item in '{}'", option, text);
    rows.push_back(fields);
  }
  return rows;
}

double ToNumber(const std::string& text, const char* option) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  EPILOC_CHECK(used == text.size() && !text.empty(), "{}: '{}' is not a number", option, text);
  return value;
}

void ApplyVariants(const VariantFlags& v, bool no_distortion, SynthOptions& o) {
  if (!v.camera.empty()) {
    const double rate = o.query.frame_rate_hz;
    ApplyQueryCameraPreset(v.camera, &o.query);
    if (v.rate_given) o.query.frame_rate_hz = rate;
  }
  bool camera_changed = !v.camera.empty();
  if (!v.size.empty()) {
    int width = 0, height = 0;
    char x = 0, rest = 0;
    EPILOC_CHECK(std::sscanf(v.size.c_str(), "%d%c%d%c", &width, &x, &height, &rest) == 3 &&
                     x == 'x' && width > 0 && height > 0,
                 "--query-size: '{}' is not WIDTHxHEIGHT", v.size);
    o.query.camera = WithSize(o.query.camera, width, height);
    camera_changed = true;
  }
  if (!v.distortion.empty()) {
    const auto rows = SplitList(v.distortion, "--query-distortion");
    EPILOC_CHECK(rows.size() >= 1 && rows.size() <= 5, "--query-distortion: 1 to 5 values");
    o.query.camera.distortion.fill(0.0);
    for (size_t i = 0; i < rows.size(); ++i) {
      EPILOC_CHECK(rows[i].size() == 1, "--query-distortion: '{}' is not k1,k2,p1,p2,k3",
                   v.distortion);
      o.query.camera.distortion[i] = ToNumber(rows[i][0], "--query-distortion");
    }
    camera_changed = true;
  }
  if (no_distortion) o.query.camera.distortion.fill(0.0);
  if (v.hfov_deg > 0) {
    o.query.camera = WithHorizontalFovDeg(o.query.camera, v.hfov_deg);
    camera_changed = true;
  }
  if (camera_changed) CheckDistortionInvertible(o.query.camera, "query camera");
  if (!v.stops.empty()) {
    o.query.stops.clear();
    for (const auto& fields : SplitList(v.stops, "--query-stops")) {
      EPILOC_CHECK(fields.size() == 2, "--query-stops: '{}' is not AT:SECONDS,...", v.stops);
      StopEvent stop;
      std::string at = fields[0];
      if (!at.empty() && at.back() == 'm') {
        at.pop_back();
        stop.at_m = ToNumber(at, "--query-stops");
      } else {
        stop.at_fraction = ToNumber(at, "--query-stops");
      }
      stop.duration_s = ToNumber(fields[1], "--query-stops");
      o.query.stops.push_back(stop);
    }
    o.query.still_when_stopped = true;
  }
  if (!v.sections.empty()) {
    o.query.sections.clear();
    for (const auto& fields : SplitList(v.sections, "--query-speed-sections")) {
      EPILOC_CHECK(fields.size() == 3, "--query-speed-sections: '{}' is not FROM:TO:MPS,...",
                   v.sections);
      o.query.sections.push_back({ToNumber(fields[0], "--query-speed-sections"),
                                  ToNumber(fields[1], "--query-speed-sections"),
                                  ToNumber(fields[2], "--query-speed-sections")});
    }
  }
  if (v.stop_at_end_s >= 0) {
    o.query.end_stop_s = v.stop_at_end_s;
    o.query.still_when_stopped = true;
  }
  if (v.motion_given) o.query.constant_acceleration = true;
  if (v.turn_in_deg > 0) {
    o.world.side_street.enabled = true;
    o.world.side_street.angle_deg = v.turn_in_deg;
    o.query.turn_in = true;
  }
  if (v.sharp_curves) {
    o.world.min_radius_m = 25.0;
    o.world.max_radius_m = 60.0;
    o.world.max_turn_deg = 90.0;
    o.world.min_straight_m = 20.0;
    o.world.max_straight_m = 50.0;
  }
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
  LidarOptions& lidar = options.lidar_options;
  app.add_option("--lidar-spacing", lidar.scan_spacing_m,
                 "LiDAR map: distance between scans along the survey path, metres")
      ->capture_default_str();
  app.add_option("--lidar-rings", lidar.num_rings, "LiDAR map: the scanner's beams")
      ->capture_default_str();
  app.add_option("--lidar-fov", lidar.azimuth_fov_deg,
                 "LiDAR map: horizontal field kept, degrees, centred on forward (360: all)")
      ->capture_default_str();
  app.add_option("--lidar-noise", lidar.range_noise_m,
                 "LiDAR map: range noise, standard deviation, metres")
      ->capture_default_str();
  app.add_flag("--lidar-scan-files", options.lidar_scan_files,
               "Also write each scan (sensor frame) into survey/lidar/ and list them in the "
               "survey's lidar.csv with their exact poses (for build-map and lidar-track)");
  bool query_only = false;
  app.add_flag("--query-only", query_only,
               "Write the query drive only (not the survey's frames): another query of a world "
               "generated before with the same seed and world options");
  app.add_option("--threads", options.num_threads, "Rendering threads")->capture_default_str();
  AppearanceFlags appearance;
  AddAppearanceFlags(app, appearance);
  VariantFlags variants;
  AddVariantOptions(app, variants, options);
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  variants.rate_given = app.count("--query-rate-hz") > 0;
  for (const char* motion :
       {"--query-stops", "--query-speed-sections", "--query-start-from-rest", "--query-stop-at-end",
        "--query-creep-mps", "--query-max-accel-mps2", "--query-turn-in-deg"}) {
    variants.motion_given = variants.motion_given || app.count(motion) > 0;
  }
  variants.exposure_s = options.query.exposure_s;  // --clean-query must not undo it

  options.lidar = !no_lidar;
  options.survey_frames = !query_only;
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
  if (app.count("--query-exposure-s") > 0) options.query.exposure_s = variants.exposure_s;
  ApplyVariants(variants, no_distortion, options);
  ApplyAppearanceFlags(appearance, options);
  Progress progress("synth", 0);
  const SynthSummary summary = GenerateSynthetic(options, out_dir, progress.Callback());
  progress.Finish();
  if (options.lidar) {
    // The map's frame travels with it, as build-map's does: anchor and render read it.
    const std::string map_path = (std::filesystem::path(out_dir) / "lidar" / "map.ply").string();
    MapSidecar sidecar =
        DescribeCloud(ReadPointCloud(map_path), options.world.origin, "synthetic world origin");
    sidecar.source_drive = "synth seed " + std::to_string(options.seed);
    sidecar.source_dir = std::filesystem::absolute(out_dir).lexically_normal().string();
    sidecar.num_scans = summary.num_lidar_scans;
    WriteMapSidecar(sidecar, SidecarPath(map_path));
  }
  std::printf(
      "%s: survey %d frames, query %d frames, %d surfaces, %d LiDAR scans (%lld points), "
      "%.1f s\n",
      out_dir.c_str(), summary.num_survey_frames, summary.num_query_frames, summary.num_surfaces,
      summary.num_lidar_scans, static_cast<long long>(summary.num_lidar_points), summary.seconds);
  return kExitOk;
}

}  // namespace epiloc
