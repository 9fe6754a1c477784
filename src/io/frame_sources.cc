// The frame sources of a drive manifest (CSV, image folder, video) and the LiDAR CSV.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <unordered_map>
#include <unordered_set>

#include <spdlog/spdlog.h>
#include <opencv2/videoio.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/position_readers.h"
#include "io_internal.h"

namespace epiloc {
namespace {

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// The last run of digits in `stem`, if any.
std::optional<frame_t> NumberInName(const std::string& stem) {
  const size_t last = stem.find_last_of("0123456789");
  if (last == std::string::npos) return std::nullopt;
  size_t first = last;
  while (first > 0 && std::isdigit(static_cast<unsigned char>(stem[first - 1]))) --first;
  const std::string digits = stem.substr(first, last - first + 1);
  if (digits.size() > 18) return std::nullopt;
  return std::stoll(digits);
}

}  // namespace

void CheckFrameOrder(const std::vector<FrameRecord>& frames, const std::string& where) {
  std::unordered_set<frame_t> seen;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!seen.insert(frames[i].frame).second) {
      Throw("{}: frame {} appears twice", where, frames[i].frame);
    }
    if (i > 0 && frames[i].timestamp_s < frames[i - 1].timestamp_s) {
      Throw("{}: frame times go backwards at frame {} ({} s after {} s)", where, frames[i].frame,
            FormatDouble(frames[i].timestamp_s), FormatDouble(frames[i - 1].timestamp_s));
    }
  }
}

FramesCsvRows::FramesCsvRows(const std::string& path, const std::string& dir, bool video)
    : csv_(path), dir_(dir), video_(video) {
  csv_.RequireColumns({"frame", "timestamp_s"});
  if (!video) csv_.RequireColumns({"image"});
}

bool FramesCsvRows::Next(FrameRecord* out, bool appended) {
  if (!(appended ? csv_.NextAppended() : csv_.Next())) return false;
  FrameRecord record;
  record.frame = csv_.GetInt("frame");
  record.timestamp_s = csv_.GetDouble("timestamp_s");
  if (csv_.HasColumn("image")) record.image = csv_.Get("image");
  record.line = csv_.line();
  if (record.frame < 0) Throw("{}: frame number {} is negative", csv_.where(), record.frame);
  const auto [it, inserted] = line_of_frame_.emplace(record.frame, csv_.line());
  if (!inserted) {
    Throw("{}: frame {} appears twice (first on line {})", csv_.where(), record.frame, it->second);
  }
  if (last_timestamp_s_ && record.timestamp_s < *last_timestamp_s_) {
    Throw("{}: timestamp {} goes backwards (previous {})", csv_.where(),
          FormatDouble(record.timestamp_s), FormatDouble(*last_timestamp_s_));
  }
  if (video_ && !record.image.empty()) {
    Throw("{}: a video drive's frames have no image path", csv_.where());
  }
  if (!video_) {
    if (record.image.empty()) Throw("{}: empty image path", csv_.where());
    const std::string image_path = ResolvePath(dir_, record.image);
    const std::string problem = FileProblem(image_path);
    if (!problem.empty()) Throw("{}: image file {} {}", csv_.where(), image_path, problem);
  }
  last_timestamp_s_ = record.timestamp_s;
  *out = std::move(record);
  return true;
}

std::vector<FrameRecord> ReadFramesCsv(const std::string& path,
                                       const std::string& dir,
                                       bool video) {
  FramesCsvRows rows(path, dir, video);
  std::vector<FrameRecord> frames;
  FrameRecord record;
  while (rows.Next(&record)) frames.push_back(record);
  return frames;
}

std::vector<FrameRecord> ReadFramesFolder(const std::string& folder,
                                          const std::string& folder_as_given,
                                          const std::string& timestamps_path,
                                          double fps,
                                          double start_s) {
  std::error_code error;
  if (!std::filesystem::is_directory(folder, error)) Throw("{}: image folder not found", folder);
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const std::string ext = Lower(entry.path().extension().string());
    if (entry.is_regular_file() && (ext == ".png" || ext == ".jpg" || ext == ".jpeg")) {
      names.push_back(entry.path().filename().string());
    }
  }
  if (names.empty()) Throw("{}: no PNG or JPEG images in the folder", folder);
  std::sort(names.begin(), names.end());

  std::vector<std::optional<frame_t>> numbers;
  bool all_numbered = true;
  for (const auto& name : names) {
    numbers.push_back(NumberInName(std::filesystem::path(name).stem().string()));
    all_numbered = all_numbered && numbers.back().has_value();
  }
  std::vector<FrameRecord> frames(names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    frames[i].frame = all_numbered ? *numbers[i] : static_cast<frame_t>(i);
    frames[i].image = (std::filesystem::path(folder_as_given) / names[i]).string();
  }
  if (all_numbered) {
    // Numbers need not be zero-padded: order by number, not by name.
    std::stable_sort(frames.begin(), frames.end(),
                     [](const FrameRecord& a, const FrameRecord& b) { return a.frame < b.frame; });
    for (size_t i = 1; i < frames.size(); ++i) {
      if (frames[i].frame == frames[i - 1].frame) {
        Throw("{}: images {} and {} have the same frame number {}", folder,
              std::filesystem::path(frames[i - 1].image).filename().string(),
              std::filesystem::path(frames[i].image).filename().string(), frames[i].frame);
      }
    }
  }

  if (!timestamps_path.empty()) {
    const std::vector<double> times = ReadTimestamps(timestamps_path);
    if (times.size() == frames.size()) {
      for (size_t i = 0; i < frames.size(); ++i) frames[i].timestamp_s = times[i];
    } else if (all_numbered && frames.back().frame < static_cast<frame_t>(times.size())) {
      // A thinned folder (KITTI style): line n holds the time of frame n.
      for (auto& f : frames) f.timestamp_s = times[static_cast<size_t>(f.frame)];
    } else {
      Throw("{}: {} timestamps for {} images in {}", timestamps_path, times.size(), frames.size(),
            folder);
    }
  } else {
    for (auto& f : frames) f.timestamp_s = start_s + (f.frame - frames.front().frame) / fps;
  }
  CheckFrameOrder(frames, timestamps_path.empty() ? folder : timestamps_path);
  return frames;
}

std::vector<FrameRecord> ReadFramesVideo(const std::string& video_path,
                                         const std::string& timestamps_path,
                                         double fps,
                                         double start_s) {
  const std::string problem = FileProblem(video_path);
  if (!problem.empty()) Throw("{}: video file {}", video_path, problem);
  cv::VideoCapture capture(video_path);
  if (!capture.isOpened()) Throw("{}: cannot open video", video_path);
  std::vector<FrameRecord> frames;
  const auto reported = static_cast<int64_t>(capture.get(cv::CAP_PROP_FRAME_COUNT));
  if (!timestamps_path.empty()) {
    const std::vector<double> times = ReadTimestamps(timestamps_path);
    if (reported > 0 && static_cast<int64_t>(times.size()) != reported) {
      spdlog::warn("{}: {} timestamps, the video reports {} frames", timestamps_path, times.size(),
                   reported);
    }
    for (size_t i = 0; i < times.size(); ++i)
      frames.push_back({static_cast<frame_t>(i), times[i], ""});
    return frames;
  }
  if (fps > 0) {
    if (reported <= 0) {
      Throw("{}: the video does not report its frame count; give a timestamps file", video_path);
    }
    for (int64_t i = 0; i < reported; ++i) frames.push_back({i, start_s + i / fps, ""});
    return frames;
  }
  // The video's own frame times: decode through it once.
  std::vector<double> times;
  bool increasing = true;
  while (capture.grab()) {
    const double t = capture.get(cv::CAP_PROP_POS_MSEC) / 1000.0;
    increasing = increasing && (times.empty() || t > times.back());
    times.push_back(t);
  }
  if (times.empty()) Throw("{}: the video has no frames", video_path);
  if (!increasing) {
    const double video_fps = capture.get(cv::CAP_PROP_FPS);
    if (!(video_fps > 0)) {
      Throw(
          "{}: the video has neither frame times nor a frame rate; give \"fps\" or \"timestamps\"",
          video_path);
    }
    for (size_t i = 0; i < times.size(); ++i) times[i] = i / video_fps;
  }
  for (size_t i = 0; i < times.size(); ++i) {
    frames.push_back({static_cast<frame_t>(i), start_s + times[i] - times[0], ""});
  }
  return frames;
}

std::vector<LidarScan> ReadLidarCsv(const std::string& path, const std::string& dir) {
  CsvReader csv(path);
  csv.RequireColumns({"scan", "timestamp_s", "path", "format", "lat_deg", "lon_deg", "alt_m", "qw",
                      "qx", "qy", "qz"});
  std::vector<LidarScan> scans;
  std::unordered_set<int64_t> seen;
  while (csv.Next()) {
    LidarScan scan;
    scan.scan = csv.GetInt("scan");
    scan.timestamp_s = csv.GetDouble("timestamp_s");
    scan.path = csv.Get("path");
    scan.format = csv.Get("format");
    scan.sensor_position = {csv.GetDouble("lat_deg"), csv.GetDouble("lon_deg"),
                            csv.GetDouble("alt_m")};
    CheckGeodetic(scan.sensor_position, csv.where());
    scan.enu_from_sensor = CheckedQuaternion(csv.GetDouble("qw"), csv.GetDouble("qx"),
                                             csv.GetDouble("qy"), csv.GetDouble("qz"), csv.where());
    if (scan.format != "kitti_bin" && scan.format != "ply" && scan.format != "pcd" &&
        scan.format != "xyz") {
      Throw("{}: unknown scan format '{}' (expected kitti_bin, ply, pcd or xyz)", csv.where(),
            scan.format);
    }
    if (!seen.insert(scan.scan).second) Throw("{}: scan {} appears twice", csv.where(), scan.scan);
    if (!scans.empty() && scan.timestamp_s < scans.back().timestamp_s) {
      Throw("{}: timestamp {} goes backwards (previous {})", csv.where(),
            FormatDouble(scan.timestamp_s), FormatDouble(scans.back().timestamp_s));
    }
    const std::string scan_path = ResolvePath(dir, scan.path);
    const std::string problem = FileProblem(scan_path);
    if (!problem.empty()) Throw("{}: scan file {} {}", csv.where(), scan_path, problem);
    std::error_code error;
    if (std::filesystem::file_size(scan_path, error) == 0) {
      Throw("{}: scan file {} is empty (0 bytes)", csv.where(), scan_path);
    }
    scans.push_back(scan);
  }
  return scans;
}

void WriteLidarCsv(const std::vector<LidarScan>& scans, const std::string& path) {
  CsvWriter csv(path, {"scan", "timestamp_s", "path", "format", "lat_deg", "lon_deg", "alt_m", "qw",
                       "qx", "qy", "qz"});
  for (const auto& s : scans) {
    const auto& q = s.enu_from_sensor;
    csv.WriteRow({std::to_string(s.scan), FormatDouble(s.timestamp_s), s.path, s.format,
                  FormatDouble(s.sensor_position.lat_deg), FormatDouble(s.sensor_position.lon_deg),
                  FormatDouble(s.sensor_position.alt_m), FormatDouble(q.w()), FormatDouble(q.x()),
                  FormatDouble(q.y()), FormatDouble(q.z())});
  }
  csv.Close();
}

}  // namespace epiloc
