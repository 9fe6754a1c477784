// The georef module's importers: trajectories from `epiloc vo`, ORB-SLAM2/3 and stella_vslam
// (ImportTrajectory: format detection, nanosecond times, KITTI times files, re-timing on a drive's
// frames), the "# drive_dir" comment, anchors (ReadAnchors), VO structure (VoStructure::Read:
// trajectory, "# segment" comments and the points CSV), and Georeference on what was read, so
// hostile numbers reach the interpolation and the similarity fits too.
//
// Input: one option byte, then up to three files separated by NUL bytes: the trajectory, a second
// file (the KITTI times file, or the VO points CSV), a third (the anchors CSV). Option bits:
//   0-1  format: auto, tum, kitti, auto
//   2    use the second file as the KITTI times file
//   3    the drive's frame times and numbers (20 frames, 0.1 s apart, numbered from 100)
//   4    relative times (with bit 3), else a time offset of 1000 s
//   5    Georeference with the anchors (method picked by bits 6-7)
//   6-7  0: all methods, 1: paper, 2: sim3, 3: piecewise; with bit 5 clear, 1 also reads the
//        VO structure and 2 the drive_dir comment
#include <cstdint>
#include <string>
#include <vector>

#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/core/error.h"
#include "epiloc/georef/anchors.h"
#include "epiloc/georef/georef.h"
#include "epiloc/georef/trajectory_import.h"
#include "fuzz_util.h"

namespace {

// Splits at the first two NUL bytes into up to three parts (missing parts are empty).
std::vector<std::string> SplitParts(const uint8_t* data, size_t size) {
  std::vector<std::string> parts(1);
  for (size_t i = 0; i < size; ++i) {
    if (data[i] == 0 && parts.size() < 3) {
      parts.emplace_back();
    } else {
      parts.back().push_back(static_cast<char>(data[i]));
    }
  }
  parts.resize(3);
  return parts;
}

std::string Write(const std::string& name, const std::string& bytes) {
  return epiloc::fuzz::WriteInput(name, reinterpret_cast<const uint8_t*>(bytes.data()),
                                  bytes.size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t bits = data[0];
  const std::vector<std::string> parts = SplitParts(data + 1, size - 1);
  const std::string trajectory_path = Write("trajectory.txt", parts[0]);
  // The VO points file is found beside the trajectory by name (VoPointsPath).
  const std::string second_path = Write("trajectory.points.csv", parts[1]);
  const std::string anchors_path = Write("anchors.csv", parts[2]);
  const int selector = (bits >> 6) & 3;
  try {
    if (!(bits & 0x20) && selector == 1) {
      const epiloc::VoStructure vo = epiloc::VoStructure::Read(trajectory_path);
      for (const epiloc::StampedPose& pose : vo.poses) (void)vo.SegmentOf(pose.frame);
      return 0;
    }
    if (!(bits & 0x20) && selector == 2) {
      (void)epiloc::TrajectoryDriveDir(trajectory_path);
    }
    epiloc::TrajectoryImportOptions options;
    const epiloc::TrajectoryFileFormat formats[] = {
        epiloc::TrajectoryFileFormat::kAuto, epiloc::TrajectoryFileFormat::kTum,
        epiloc::TrajectoryFileFormat::kKitti, epiloc::TrajectoryFileFormat::kAuto};
    options.format = formats[bits & 3];
    if (bits & 0x04) options.times_path = second_path;
    std::vector<epiloc::GeorefFrame> frames;
    if (bits & 0x08) {
      for (int i = 0; i < 20; ++i) {
        options.frame_times.push_back(0.1 * i);
        options.frame_numbers.push_back(100 + i);
        frames.push_back({100 + i, 0.1 * i});
      }
    }
    if ((bits & 0x10) && (bits & 0x08)) {
      options.relative_times = true;
    } else if (bits & 0x10) {
      options.time_offset_s = 1000.0;
    }
    const epiloc::ImportedTrajectory trajectory =
        epiloc::ImportTrajectory(trajectory_path, options);
    const auto& poses = trajectory.poses;
    for (const double t : {poses.front().timestamp_s, poses.back().timestamp_s,
                           0.5 * (poses.front().timestamp_s + poses.back().timestamp_s)}) {
      (void)epiloc::InterpolatePose(poses, t, 1.0);
    }
    if (bits & 0x20) {
      const epiloc::AnchorSet anchors = epiloc::ReadAnchors(anchors_path);
      epiloc::GeorefOptions georef;
      georef.methods =
          selector == 0
              ? epiloc::ParseGeorefMethods("all")
              : std::vector<epiloc::GeorefMethod>{static_cast<epiloc::GeorefMethod>(selector - 1)};
      (void)epiloc::Georeference(trajectory, anchors, frames, georef);
    }
  } catch (const epiloc::Error&) {
  }
  return 0;
}
