#include <cstdio>
#include <string>
#include <vector>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/kitti.h"

namespace epiloc {
namespace {

// "START:STOP:STEP", "START:STOP" or "START:" (STOP exclusive, empty = to the end).
void ParseFrameRange(const std::string& text, KittiImportOptions& options) {
  std::vector<std::string> parts;
  size_t begin = 0;
  while (true) {
    const size_t colon = text.find(':', begin);
    parts.push_back(text.substr(begin, colon - begin));
    if (colon == std::string::npos) break;
    begin = colon + 1;
  }
  if (parts.size() < 2 || parts.size() > 3) {
    Throw("--frames '{}': expected START:STOP[:STEP]", text);
  }
  const std::string where = "--frames '" + text + "'";
  options.start = parts[0].empty() ? 0 : ParseInt(parts[0], where);
  options.stop = parts[1].empty() ? -1 : ParseInt(parts[1], where);
  options.step = parts.size() == 3 && !parts[2].empty() ? ParseInt(parts[2], where) : 1;
}

}  // namespace

int RunImportKitti(int argc, char** argv) {
  CLI::App app(
      "Convert a KITTI raw synced drive (calibration files one level up) into a drive directory. "
      "Positions refer to the chosen rectified camera's optical centre; the OXTS solution is "
      "written as ground truth, GNSS equals it unless --gps-noise simulates a consumer GPS.",
      "import-kitti");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  KittiImportOptions options;
  std::string frames;
  app.add_option("--raw", options.raw_drive_dir, "KITTI drive folder <DATE>/<DATE>_drive_<N>_sync")
      ->required();
  app.add_option("--camera", options.camera, "KITTI camera 0-3")
      ->check(CLI::Range(0, 3))
      ->capture_default_str();
  app.add_option("--frames", frames, "Frame selection START:STOP:STEP (STOP exclusive)");
  app.add_option("--gps-noise", options.gps_noise_sigma_m,
                 "Simulated consumer GPS error, 1-sigma per horizontal axis in metres (0 = none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--seed", options.seed, "Seed of the simulated GPS")->capture_default_str();
  std::string oxts_positions = "fused";
  app.add_option("--oxts-positions", oxts_positions,
                 "fused: OXTS positions made consistent with the unit's velocity, each weighted "
                 "by its reported accuracy; raw: as recorded")
      ->check(CLI::IsMember({"fused", "raw"}))
      ->capture_default_str();
  std::string frame_time = "auto";
  app.add_option("--frame-time", frame_time,
                 "trigger: a frame's time is the Velodyne's forward-facing time, which triggers "
                 "the cameras (17 ms before the image timestamp on drive 0005), the truth "
                 "interpolated there; image: the image timestamp, the truth at the OXTS records; "
                 "auto: trigger when velodyne_points/timestamps.txt is there, image otherwise")
      ->check(CLI::IsMember({"auto", "image", "trigger"}))
      ->capture_default_str();
  app.add_option("--out", options.out_dir, "Drive directory to write")->required();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  if (!frames.empty()) ParseFrameRange(frames, options);
  options.oxts_positions = oxts_positions == "raw" ? KittiImportOptions::OxtsPositions::kRaw
                                                   : KittiImportOptions::OxtsPositions::kFused;
  options.frame_time = frame_time == "trigger" ? KittiImportOptions::FrameTime::kTrigger
                       : frame_time == "image" ? KittiImportOptions::FrameTime::kImage
                                               : KittiImportOptions::FrameTime::kAuto;

  const Drive drive = ImportKitti(options);
  std::printf("%s: drive '%s' with %zu frames, %zu GNSS samples, %zu LiDAR scans\n",
              options.out_dir.c_str(), drive.name.c_str(), drive.frames.size(),
              drive.gnss.samples.size(), drive.lidar.size());
  return kExitOk;
}

}  // namespace epiloc
