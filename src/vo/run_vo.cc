#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>

#include <fmt/format.h>

#include "epiloc/core/csv.h"
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
                       const std::string& drive_name,
                       const std::string& drive_dir) {
  std::vector<std::string> comments;
  comments.push_back(fmt::format(
      "epiloc vo{}: world_from_cam of each posed frame (camera x right, y down, z forward), "
      "relative scale",
      drive_name.empty() ? "" : " of drive " + drive_name));
  if (!drive_dir.empty()) {
    comments.push_back("drive_dir " + std::filesystem::absolute(drive_dir).lexically_normal().string());
  }
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

std::string VoPointsPath(const std::string& trajectory_path) {
  std::filesystem::path path(trajectory_path);
  path.replace_extension(".points.csv");
  return path.string();
}

void WriteVoPoints(const std::vector<VoPoint>& points, const std::string& path) {
  CsvWriter writer(path, {"x", "y", "z", "segment", "first_frame", "last_frame", "observations",
                          "parallax_deg"});
  for (const VoPoint& p : points) {
    writer.WriteRow({FormatDouble(p.point_in_world.x()), FormatDouble(p.point_in_world.y()),
                     FormatDouble(p.point_in_world.z()), std::to_string(p.segment),
                     std::to_string(p.first_frame), std::to_string(p.last_frame),
                     std::to_string(p.observations), FormatFixed(p.parallax_deg, 3)});
  }
  writer.Close();
}

std::vector<VoPoint> ReadVoPoints(const std::string& path) {
  CsvReader reader(path);
  reader.RequireColumns({"x", "y", "z", "segment", "first_frame", "last_frame", "observations"});
  std::vector<VoPoint> points;
  while (reader.Next()) {
    VoPoint p;
    p.point_in_world = {reader.GetDouble("x"), reader.GetDouble("y"), reader.GetDouble("z")};
    if (!p.point_in_world.allFinite()) Throw("{}: a coordinate is not finite", reader.where());
    p.segment = static_cast<int>(reader.GetInt("segment"));
    p.first_frame = reader.GetInt("first_frame");
    p.last_frame = reader.GetInt("last_frame");
    p.observations = static_cast<int>(reader.GetInt("observations"));
    p.parallax_deg = reader.GetOptionalDouble("parallax_deg").value_or(NAN);
    if (p.last_frame < p.first_frame || p.observations < 1) {
      Throw("{}: last_frame before first_frame or no observations", reader.where());
    }
    points.push_back(p);
  }
  return points;
}

}  // namespace epiloc
