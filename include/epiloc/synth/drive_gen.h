// Generation of a complete synthetic data set: a street world, a survey drive and a query drive
// through it (frames, GNSS, exact ground truth, calibration; epiloc's drive directory format),
// a LiDAR map sampled from the survey path, the world description and a top view.
//
// Layout of the output directory:
//   world.json         options, centreline, markers and surfaces of the world (WriteWorldJson)
//   top_view.png       roads, buildings, cars, survey (blue) and query (red) paths, LiDAR scans
//   survey/, query/    drive directories (drive.json, frames.csv, gnss.csv, ground_truth.csv,
//                      images/NNNNNN.png; survey/lidar.csv when per-scan files are written)
//   lidar/map.ply      all LiDAR points in the world ENU frame (x y z intensity rgb)
//   lidar/scans.csv    scan number, time, sensor position (geodetic and world ENU) and
//                      orientation (enu_from_sensor, local ENU, quaternion w x y z)
//   appearance.json, survey|query/moving_objects.csv, query/world.json,
//   query/parked_cars_changed.csv   the appearance variants (WriteAppearance)
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "epiloc/core/progress.h"
#include "epiloc/synth/appearance.h"
#include "epiloc/synth/lidar.h"
#include "epiloc/synth/trajectory.h"
#include "epiloc/synth/world.h"

namespace epiloc {

struct SynthOptions {
  double length_m = 300.0;  // driven length of the survey, metres (the query drives 20 m less)
  uint64_t seed = 1;        // world, noise and GNSS all derive from it
  WorldOptions world;       // street layout; its length_m and seed are set from the two above
  DriveOptions survey = DriveOptions::Survey();  // survey drive (see DriveOptions::Survey)
  DriveOptions query = DriveOptions::Query();    // query drive (see DriveOptions::Query)
  bool lidar = true;                             // simulate the LiDAR map from the survey path
  // Render and write the survey drive (off: the query drive only, e.g. another query of a world
  // whose survey was generated before with the same world options and seed).
  bool survey_frames = true;
  LidarOptions lidar_options;                    // scanner model and scan spacing
  bool lidar_scan_files = false;  // also write each scan (sensor frame) into survey/lidar/
  int num_threads = 2;            // rendering and scanning threads
  int png_compression = 1;        // PNG compression level of the frames (0-9)

  // Appearance variants (all off by default): moving cars, parked cars changed, sun per drive.
  // Vegetation: world.vegetation; exposure and white balance: survey/query.render.
  AppearanceOptions appearance;

  // Throws Error naming the first invalid field.
  void Check() const;
  // `world` with length_m and seed filled in.
  WorldOptions ResolvedWorldOptions() const;
};

// What was generated, and how long it took.
struct SynthSummary {
  int num_survey_frames = 0;
  int num_query_frames = 0;
  int num_lidar_scans = 0;
  int64_t num_lidar_points = 0;
  int num_surfaces = 0;
  double seconds = 0.0;  // wall-clock time of the whole generation
};

// Generates the data set into `out_dir` (created if missing; existing files are overwritten).
// `progress` (optional, called from worker threads, serialised) gets (units done, total) over
// all frames and LiDAR scans. Defaults take ~30 s on 2 cores. Throws Error on invalid options or
// I/O failure.
SynthSummary GenerateSynthetic(const SynthOptions& options,
                               const std::string& out_dir,
                               const ProgressCallback& progress = nullptr);

// A trajectory to draw in the top view.
struct TopViewTrack {
  std::vector<Eigen::Vector3d> points_in_world;
  cv::Scalar bgr;
  bool dots = false;  // draw points instead of a line
  std::string label;  // legend entry (none if empty)
};

// A north-up map of the world (road, pavements, buildings, cars, poles) with the tracks, at most
// `max_size_px` on its longer side, with a scale bar.
cv::Mat DrawTopView(const World& world,
                    const std::vector<TopViewTrack>& tracks,
                    int max_size_px = 1200);

}  // namespace epiloc
