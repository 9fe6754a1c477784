#include <cstdio>
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "cli_common.h"
#include "epiloc/anchor/lidar_track.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/io/drive.h"

namespace epiloc {

int RunLidarTrack(int argc, char** argv) {
  CLI::App app(
      "Check a drive's position track against its LiDAR scans: each scan registered to the one "
      "before (point-to-plane ICP, seeded by the track), the steps compared with the track's "
      "(length, direction, turn). With --out, writes a copy of the drive whose scans and ground "
      "truth follow the LiDAR's path (the attitude kept; the path placed at the track's mean "
      "position; the GNSS untouched): a map and a truth that agree with each other.",
      "lidar-track");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string drive_dir, out_dir, steps_path;
  LidarTrackOptions options;
  app.add_option("--drive", drive_dir, "Drive directory with LiDAR scans (drive.json 'lidar')")
      ->required();
  app.add_option("--out", out_dir, "Write the corrected drive to this directory");
  app.add_option("--steps", steps_path, "Write the per-pair figures to this CSV");
  AddScanRangeOptions(app, options.min_range_m, options.max_range_m);
  app.add_option("--voxel", options.voxel_m, "Scans thinned to one point per voxel, metres")
      ->capture_default_str();
  app.add_option("--min-inlier-share", options.min_inlier_share,
                 "A pair with fewer points on the other scan's surfaces keeps the track's step")
      ->capture_default_str();
  app.add_option("--threads", options.num_threads, "Worker threads")->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  std::vector<NamedPath> outputs;
  if (!steps_path.empty()) outputs.push_back({"--steps", steps_path});
  if (!out_dir.empty() && !std::filesystem::exists(out_dir)) {
    outputs.push_back({"--out", out_dir});  // a new folder holds no input; its parent must exist
  } else if (!out_dir.empty()) {
    for (const char* file :
         {"drive.json", "frames.csv", "gnss.csv", "ground_truth.csv", "lidar.csv"}) {
      outputs.push_back({"--out", (std::filesystem::path(out_dir) / file).string()});
    }
  }
  CheckCommandOutputs(outputs, {{"--drive", drive_dir}});
  options.Check();

  const Drive drive = LoadDrive(drive_dir);
  if (drive.lidar.empty())
    Throw("{}: the drive has no LiDAR scans (drive.json 'lidar')", drive_dir);
  const EnuFrame frame(drive.lidar.front().sensor_position);
  Progress progress("lidar-track", 0);
  const LidarTrack track = EstimateLidarTrack(drive, frame, options, progress.Callback());
  progress.Finish();

  if (!steps_path.empty()) {
    CsvWriter csv(steps_path, {"from_scan", "to_scan", "registered", "inlier_share", "rms_m",
                               "lidar_m", "track_m", "pitch_deg", "heading_deg",
                               "turn_difference_deg", "yaw_difference_deg", "cumulative_yaw_deg",
                               "correction_e_m", "correction_n_m", "correction_u_m", "message"});
    for (size_t i = 0; i < track.steps.size(); ++i) {
      const LidarTrackStep& s = track.steps[i];
      const Eigen::Vector3d& c = track.correction_m[i + 1];
      csv.WriteRow(
          {std::to_string(s.from_scan), std::to_string(s.to_scan), s.registered ? "1" : "0",
           fmt::format("{:.3f}", s.inlier_share), fmt::format("{:.4f}", s.rms_m),
           fmt::format("{:.4f}", s.lidar_m), fmt::format("{:.4f}", s.track_m),
           fmt::format("{:.3f}", s.pitch_deg), fmt::format("{:.3f}", s.heading_deg),
           fmt::format("{:.3f}", s.turn_difference_deg),
           fmt::format("{:.3f}", s.yaw_difference_deg),
           fmt::format("{:.3f}", track.cumulative_yaw_deg[i + 1]), fmt::format("{:.3f}", c.x()),
           fmt::format("{:.3f}", c.y()), fmt::format("{:.3f}", c.z()), s.message});
    }
    csv.Close();
  }
  const double ratio = track.lidar_length_m > 0 ? track.track_length_m / track.lidar_length_m : 1.0;
  std::printf(
      "lidar-track: %d of %zu pairs registered; the track's steps are %.2f %% of the scans' "
      "(%.2f m against %.2f m); its direction of travel differs from theirs by %+.2f deg in "
      "pitch and %+.2f deg in heading (medians; up to %.2f and %.2f deg); turns agree within "
      "%.2f deg per pair, its heading turns away from theirs by up to %.2f deg along the drive "
      "(%+.2f at the end); corrections up to %.2f m\n",
      track.num_registered, track.steps.size(), 100.0 * ratio, track.track_length_m,
      track.lidar_length_m, track.median_pitch_deg, track.median_heading_deg,
      track.max_abs_pitch_deg, track.max_abs_heading_deg, track.max_turn_difference_deg,
      track.max_abs_cumulative_yaw_deg, track.cumulative_yaw_deg.back(), track.max_correction_m);
  for (const LidarTrackStep& s : track.steps) {
    if (!s.registered) spdlog::warn("scans {} -> {}: {}", s.from_scan, s.to_scan, s.message);
  }
  if (!out_dir.empty()) {
    WriteDrive(CorrectDriveTrack(drive, frame, track), out_dir);
    std::printf("lidar-track: corrected drive written to %s\n", out_dir.c_str());
  }
  return kExitOk;
}

}  // namespace epiloc
