#include "epiloc/georef/trajectory_import.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <utility>

#include <fmt/format.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/stella_map.h"

namespace epiloc {
namespace {

const std::vector<std::string> kFormatNames = {"auto", "tum", "kitti", "stella_map"};
constexpr double kNanosecondThreshold = 1e14;  // no plausible time in seconds is this large
constexpr double kSameTime_s = 1e-3;

// Number of whitespace-separated tokens of the first data line (0 if none).
size_t FirstLineTokens(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open trajectory file", path);
  std::string line;
  while (ReadLine(in, line, path, 0)) {
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    std::istringstream tokens(trimmed);
    std::string token;
    size_t count = 0;
    while (tokens >> token) ++count;
    return count;
  }
  return 0;
}

}  // namespace

TrajectoryFileFormat ParseTrajectoryFileFormat(const std::string& name) {
  for (size_t i = 0; i < kFormatNames.size(); ++i) {
    if (kFormatNames[i] == name) return static_cast<TrajectoryFileFormat>(i);
  }
  Throw("unknown trajectory format '{}' (known: {})", name, fmt::join(kFormatNames, ", "));
}

void TrajectoryImportOptions::Check() const {
  EPILOC_CHECK(std::isfinite(time_offset_s), "--time-offset-s must be finite");
  EPILOC_CHECK(!relative_times || !frame_times.empty(),
               "--relative-times needs the drive's frame times (--drive)");
  EPILOC_CHECK(frame_numbers.empty() || frame_numbers.size() == frame_times.size(),
               "trajectory import: {} frame numbers for {} frame times", frame_numbers.size(),
               frame_times.size());
  EPILOC_CHECK(!relative_times || time_offset_s == 0.0,
               "give either --relative-times or --time-offset-s, not both");
}

ImportedTrajectory ImportTrajectory(const std::string& path,
                                    const TrajectoryImportOptions& options,
                                    StellaMap* stella_map) {
  options.Check();
  ImportedTrajectory trajectory;
  trajectory.path = path;
  bool on_drive_clock = false;  // KITTI poses timed by the drive's frames
  trajectory.format = options.format;
  if (trajectory.format == TrajectoryFileFormat::kAuto && IsMessagePackFile(path)) {
    trajectory.format = TrajectoryFileFormat::kStellaMap;
  }
  if (trajectory.format == TrajectoryFileFormat::kAuto) {
    const size_t tokens = FirstLineTokens(path);
    if (tokens == 8) {
      trajectory.format = TrajectoryFileFormat::kTum;
    } else if (tokens == 12) {
      trajectory.format = TrajectoryFileFormat::kKitti;
    } else {
      Throw(
          "{}: cannot tell the trajectory format: the first line has {} numbers (TUM: 8, "
          "KITTI: 12); give --vo-format",
          path, tokens);
    }
  }
  EPILOC_CHECK(trajectory.format == TrajectoryFileFormat::kKitti || options.times_path.empty(),
               "{}: a times file applies to KITTI poses only", path);
  if (trajectory.format == TrajectoryFileFormat::kTum) {
    trajectory.poses = ReadTumPoses(path);
    if (!trajectory.poses.empty() && trajectory.poses.front().timestamp_s > kNanosecondThreshold) {
      for (StampedPose& pose : trajectory.poses) pose.timestamp_s *= 1e-9;
    }
  } else if (trajectory.format == TrajectoryFileFormat::kStellaMap) {
    StellaMap map = ReadStellaMap(path);
    trajectory.poses = map.keyframes;
    if (stella_map) *stella_map = std::move(map);
  } else {
    trajectory.poses = ReadKittiPoses(path, options.times_path);
    if (options.times_path.empty() && !options.frame_times.empty()) {
      on_drive_clock = true;
      if (trajectory.poses.size() != options.frame_times.size()) {
        Throw("{}: {} KITTI poses but the drive has {} frames; give the times file (--vo-times)",
              path, trajectory.poses.size(), options.frame_times.size());
      }
      for (size_t i = 0; i < trajectory.poses.size(); ++i) {
        trajectory.poses[i].timestamp_s = options.frame_times[i];
      }
    }
  }
  if (trajectory.poses.empty()) Throw("{}: the trajectory has no poses", path);
  // Relative times count from the drive's first frame; poses timed by the frames already do.
  const double offset = !options.relative_times ? options.time_offset_s
                        : on_drive_clock        ? 0.0
                                                : options.frame_times.front();
  for (size_t i = 0; i < trajectory.poses.size(); ++i) {
    StampedPose& pose = trajectory.poses[i];
    pose.timestamp_s += offset;
    if (i > 0 && pose.timestamp_s <= trajectory.poses[i - 1].timestamp_s) {
      Throw("{}: timestamp {} is not after the previous one", Where(path, pose.line),
            FormatDouble(pose.timestamp_s));
    }
  }
  if (!options.frame_numbers.empty()) {
    for (StampedPose& pose : trajectory.poses) {
      const auto after = std::lower_bound(options.frame_times.begin(), options.frame_times.end(),
                                          pose.timestamp_s - kSameTime_s);
      pose.frame = after != options.frame_times.end() &&
                           std::abs(*after - pose.timestamp_s) <= kSameTime_s
                       ? options.frame_numbers[after - options.frame_times.begin()]
                       : kInvalidFrame;
    }
  }
  return trajectory;
}

std::string TrajectoryDriveDir(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open trajectory file", path);
  const std::string key = "# drive_dir ";
  std::string line;
  while (ReadLine(in, line, path, 0)) {
    if (line.rfind(key, 0) == 0) return Trim(line.substr(key.size()));
    if (!line.empty() && line[0] != '#') break;  // comments come first
  }
  return "";
}

std::optional<Rigid3d> InterpolatePose(const std::vector<StampedPose>& poses,
                                       double timestamp_s,
                                       double max_gap_s) {
  if (poses.empty()) return std::nullopt;
  const auto after =
      std::lower_bound(poses.begin(), poses.end(), timestamp_s,
                       [](const StampedPose& pose, double t) { return pose.timestamp_s < t; });
  if (after != poses.end() && after->timestamp_s - timestamp_s <= kSameTime_s) {
    return after->world_from_cam;
  }
  if (after != poses.begin() && timestamp_s - std::prev(after)->timestamp_s <= kSameTime_s) {
    return std::prev(after)->world_from_cam;
  }
  if (after == poses.begin() || after == poses.end()) return std::nullopt;
  const StampedPose& a = *std::prev(after);
  const StampedPose& b = *after;
  if (b.timestamp_s - a.timestamp_s > max_gap_s) return std::nullopt;
  const double w = (timestamp_s - a.timestamp_s) / (b.timestamp_s - a.timestamp_s);
  return Rigid3d(a.world_from_cam.rotation.slerp(w, b.world_from_cam.rotation),
                 (1.0 - w) * a.world_from_cam.translation + w * b.world_from_cam.translation);
}

}  // namespace epiloc
