#include <chrono>
#include <future>

#include <fmt/format.h>

#include "epiloc/core/error.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/io/pose_files.h"
#include "epiloc/vo/visual_odometry.h"

namespace epiloc {

VoResult RunVisualOdometry(const Drive& drive,
                           const VoOptions& options,
                           const ProgressCallback& progress) {
  options.Check();
  EPILOC_CHECK(!drive.frames.empty(), "{}: the drive has no frames", drive.dir);
  const auto start = std::chrono::steady_clock::now();
  const FrameReader reader(drive);
  VisualOdometry odometry(drive.camera, options);
  const size_t n = reader.size();
  // Decoding the next frame overlaps with tracking the current one.
  std::future<cv::Mat> next = std::async(std::launch::async, [&] { return reader.ReadGrey(0); });
  for (size_t i = 0; i < n; ++i) {
    const cv::Mat image = next.get();
    if (i + 1 < n) {
      next = std::async(std::launch::async, [&reader, i] { return reader.ReadGrey(i + 1); });
    }
    odometry.ProcessFrame(drive.frames[i].frame, drive.frames[i].timestamp_s, image);
    if (progress) progress(static_cast<int64_t>(i + 1), static_cast<int64_t>(n));
  }
  odometry.Finish();
  VoResult result = odometry.Result();
  result.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

void WriteVoTrajectory(const VoResult& result,
                       const std::string& path,
                       const std::string& drive_name) {
  std::vector<std::string> comments;
  comments.push_back(fmt::format(
      "epiloc vo{}: world_from_cam of each posed frame (camera x right, y down, z forward), "
      "relative scale",
      drive_name.empty() ? "" : " of drive " + drive_name));
  comments.push_back("timestamp tx ty tz qx qy qz qw");
  for (const VoSegment& s : result.segments) {
    comments.push_back(fmt::format("segment {} frames {}..{} poses {} keyframes {} join_scale {}",
                                   s.id, s.first_frame, s.last_frame, s.num_poses, s.num_keyframes,
                                   s.join_scale));
  }
  std::vector<StampedPose> poses;
  poses.reserve(result.poses.size());
  for (const VoFramePose& p : result.poses) {
    StampedPose pose;
    pose.timestamp_s = p.timestamp_s;
    pose.frame = p.frame;
    pose.world_from_cam = p.world_from_cam;
    poses.push_back(pose);
  }
  WriteTumPoses(poses, path, comments);
}

}  // namespace epiloc
