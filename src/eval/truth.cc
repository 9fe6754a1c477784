#include "epiloc/eval/truth.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/kitti.h"
#include "epiloc/io/pose_files.h"
#include "epiloc/io/position_readers.h"

namespace epiloc {
namespace fs = std::filesystem;
namespace {

const std::vector<std::string> kFormatNames = {"auto",        "drive", "kitti_oxts", "tum",
                                               "kitti_poses", "ndt",   "csv"};

// Whitespace-separated numbers of one line; nullopt if a token is not a number.
std::optional<std::vector<double>> SplitNumbers(const std::string& line, char separator) {
  std::vector<double> numbers;
  std::string token;
  std::istringstream in(line);
  while (separator == ' ' ? static_cast<bool>(in >> token)
                          : static_cast<bool>(std::getline(in, token, separator))) {
    token = Trim(token);
    char* end = nullptr;
    const double value = std::strtod(token.c_str(), &end);
    if (token.empty() || end != token.c_str() + token.size()) return std::nullopt;
    numbers.push_back(value);
  }
  return numbers;
}

// First line that is neither blank nor a '#' comment ("" if none).
std::string FirstDataLine(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open ground truth", path);
  std::string line;
  while (ReadLine(in, line, path, 0)) {
    const std::string trimmed = Trim(line);
    if (!trimmed.empty() && trimmed[0] != '#') return trimmed;
  }
  return "";
}

Eigen::Matrix3d Rz(double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

// Appends a sample, checking that time increases.
void Append(PositionTrack& track, PositionSample sample, const std::string& where) {
  if (!std::isfinite(sample.timestamp_s)) Throw("{}: non-finite timestamp", where);
  if (!track.samples.empty() && sample.timestamp_s <= track.samples.back().timestamp_s) {
    Throw("{}: timestamp {} is not after the previous one ({})", where,
          FormatDouble(sample.timestamp_s), FormatDouble(track.samples.back().timestamp_s));
  }
  track.samples.push_back(std::move(sample));
}

const Geodetic& RequireOrigin(const TruthOptions& options,
                              const std::string& path,
                              const std::string& format) {
  if (!options.origin) {
    Throw("{}: {} ground truth is in local metres; give its origin (--truth-origin LAT,LON,ALT)",
          path, format);
  }
  return *options.origin;
}

// The position `lever_arm` (sensor frame) away from a sensor at `position_in_enu`.
Eigen::Vector3d ApplyLeverArm(const Eigen::Vector3d& position_in_enu,
                              const Eigen::Matrix3d& enu_from_sensor,
                              const std::optional<Eigen::Vector3d>& lever_arm) {
  return lever_arm ? Eigen::Vector3d(position_in_enu + enu_from_sensor * *lever_arm)
                   : position_in_enu;
}

PositionTrack ReadKittiOxtsTruth(const std::string& path, const TruthOptions& options) {
  const std::string dir =
      fs::is_directory(fs::path(path) / "oxts") ? (fs::path(path) / "oxts").string() : path;
  PositionTrack track;
  track.source = dir;
  for (const OxtsRecord& r : ReadKittiOxts(dir)) {
    PositionSample sample;
    sample.timestamp_s = r.timestamp_s;
    sample.frame = r.frame;
    const EnuFrame local(r.position);
    sample.position = local.ToGeodetic(ApplyLeverArm(Eigen::Vector3d::Zero(),
                                                     EnuFromImu(r.roll_rad, r.pitch_rad, r.yaw_rad),
                                                     options.lever_arm_m));
    Append(track, sample, Where(fs::path(dir) / "timestamps.txt", r.frame + 1));
  }
  return track;
}

// TUM and KITTI pose files are parsed by io/pose_files.h (shared with georef); only positions
// are used here.
PositionTrack ReadTumTruth(const std::string& path, const TruthOptions& options) {
  const EnuFrame enu(RequireOrigin(options, path, "TUM"));
  const Eigen::Matrix3d enu_from_pose = EnuFromPoseFrame(options.yaw_deg);
  PositionTrack track;
  track.source = path;
  for (const StampedPose& pose : ReadTumPoses(path)) {
    PositionSample sample;
    sample.timestamp_s = pose.timestamp_s;
    sample.position = enu.ToGeodetic(enu_from_pose * pose.world_from_cam.translation);
    Append(track, sample, Where(path, pose.line));
  }
  return track;
}

PositionTrack ReadKittiPosesTruth(const std::string& path, const TruthOptions& options) {
  const EnuFrame enu(RequireOrigin(options, path, "KITTI poses"));
  const Eigen::Matrix3d enu_from_pose = EnuFromPoseFrame(options.yaw_deg) * ZUpFromCameraAxes();
  PositionTrack track;
  track.source = path;
  for (const StampedPose& pose :
       ReadKittiPoses(path, options.times_path, /*check_rotation=*/false)) {
    PositionSample sample;
    sample.frame = pose.frame;
    sample.timestamp_s = pose.timestamp_s;
    sample.position = enu.ToGeodetic(enu_from_pose * pose.world_from_cam.translation);
    Append(track, sample, Where(path, pose.line));
  }
  return track;
}

PositionTrack ReadNdtTruth(const std::string& path, const TruthOptions& options) {
  const EnuFrame enu(RequireOrigin(options, path, "NDT"));
  const Eigen::Matrix3d enu_from_map = EnuFromPoseFrame(options.yaw_deg);
  PositionTrack track;
  track.source = path;
  const std::string first = FirstDataLine(path);
  const auto numbers = SplitNumbers(first, ',');
  if (numbers && numbers->size() == 7) {  // headerless: t, x, y, z, roll, pitch, yaw
    std::ifstream in(path);
    std::string line;
    int64_t line_number = 0;
    while (ReadLine(in, line, path, line_number + 1)) {
      ++line_number;
      const std::string trimmed = Trim(line);
      if (trimmed.empty() || trimmed[0] == '#') continue;
      const std::string where = Where(path, line_number);
      const auto v = SplitNumbers(trimmed, ',');
      if (!v || v->size() != 7) {
        Throw("{}: expected 7 numbers (time,x,y,z,roll,pitch,yaw), got '{}'", where, trimmed);
      }
      for (const double x : *v) {
        if (!std::isfinite(x)) Throw("{}: non-finite number in '{}'", where, trimmed);
      }
      const auto& p = *v;
      PositionSample sample;
      sample.timestamp_s = p[0];
      const Eigen::Vector3d x_in_enu = enu_from_map * Eigen::Vector3d(p[1], p[2], p[3]);
      const Eigen::Matrix3d enu_from_sensor = enu_from_map * EnuFromImu(p[4], p[5], p[6]);
      sample.position =
          enu.ToGeodetic(ApplyLeverArm(x_in_enu, enu_from_sensor, options.lever_arm_m));
      Append(track, sample, where);
    }
    return track;
  }
  CsvReader csv(path);
  const auto pick = [&](const std::vector<std::string>& names) -> std::string {
    for (const auto& name : names) {
      if (csv.HasColumn(name)) return name;
    }
    Throw("{}: missing NDT column '{}' (header: {})", Where(path, 1), fmt::join(names, "|"),
          fmt::join(csv.header(), ","));
  };
  const std::string t = pick({"time", "timestamp", "timestamp_s"});
  const std::string x = pick({"x", "x_m"}), y = pick({"y", "y_m"}), z = pick({"z", "z_m"});
  const std::string roll = pick({"roll", "roll_rad"}), pitch = pick({"pitch", "pitch_rad"});
  const std::string yaw = pick({"yaw", "yaw_rad"});
  while (csv.Next()) {
    PositionSample sample;
    sample.timestamp_s = csv.GetDouble(t);
    const Eigen::Vector3d x_in_enu =
        enu_from_map * Eigen::Vector3d(csv.GetDouble(x), csv.GetDouble(y), csv.GetDouble(z));
    const Eigen::Matrix3d enu_from_sensor =
        enu_from_map * EnuFromImu(csv.GetDouble(roll), csv.GetDouble(pitch), csv.GetDouble(yaw));
    sample.position = enu.ToGeodetic(ApplyLeverArm(x_in_enu, enu_from_sensor, options.lever_arm_m));
    if (csv.HasColumn("frame") && !csv.Get("frame").empty()) sample.frame = csv.GetInt("frame");
    Append(track, sample, csv.where());
  }
  return track;
}

}  // namespace

TruthFormat ParseTruthFormat(const std::string& name) {
  for (size_t i = 0; i < kFormatNames.size(); ++i) {
    if (kFormatNames[i] == name) return static_cast<TruthFormat>(i);
  }
  Throw("unknown ground-truth format '{}' (known: {})", name, fmt::join(kFormatNames, ", "));
}

std::string TruthFormatName(TruthFormat format) {
  return kFormatNames[static_cast<size_t>(format)];
}

void TruthOptions::Check() const {
  if (origin) CheckGeodetic(*origin, "--truth-origin");
  EPILOC_CHECK(std::isfinite(yaw_deg), "--truth-yaw-deg must be finite");
  EPILOC_CHECK(!lever_arm_m || lever_arm_m->allFinite(), "--truth-lever-arm must be finite");
}

Eigen::Matrix3d EnuFromPoseFrame(double yaw_deg) { return Rz(yaw_deg * M_PI / 180.0); }

Eigen::Matrix3d ZUpFromCameraAxes() {
  Eigen::Matrix3d m;
  m << 1, 0, 0,  //
      0, 0, 1,   //
      0, -1, 0;
  return m;
}

TruthFormat DetectTruthFormat(const std::string& path) {
  const fs::path p(path);
  if (!fs::exists(p)) Throw("{}: no such file or directory (ground truth)", path);
  if (fs::is_directory(p)) {
    if (fs::exists(p / "drive.json")) return TruthFormat::kDrive;
    if ((fs::is_directory(p / "data") && fs::exists(p / "timestamps.txt")) ||
        fs::is_directory(p / "oxts")) {
      return TruthFormat::kKittiOxts;
    }
    Throw(
        "{}: directory is neither a drive (drive.json) nor a KITTI OXTS folder; give "
        "--truth-format",
        path);
  }
  const std::string line = FirstDataLine(path);
  if (const auto numbers = SplitNumbers(line, ' ')) {
    if (numbers->size() == 8) return TruthFormat::kTum;
    if (numbers->size() == 12) return TruthFormat::kKittiPoses;
  }
  if (const auto numbers = SplitNumbers(line, ',')) {
    if (numbers->size() == 7) return TruthFormat::kNdt;
  }
  const std::vector<std::string> header = SplitCsvLine(line);
  const auto has = [&](const std::string& name) {
    return std::find(header.begin(), header.end(), name) != header.end();
  };
  if (has("timestamp_s") && (has("lat_deg") || has("x_m"))) return TruthFormat::kCsv;
  if (has("roll") && has("pitch") && has("yaw")) return TruthFormat::kNdt;
  Throw(
      "{}: cannot tell the ground-truth format from its first line '{}'; give --truth-format "
      "(drive, kitti_oxts, tum, kitti_poses, ndt, csv)",
      path, line);
}

PositionTrack ReadTruth(const std::string& path, const TruthOptions& options) {
  options.Check();
  const TruthFormat format =
      options.format == TruthFormat::kAuto ? DetectTruthFormat(path) : options.format;
  if (options.lever_arm_m && format != TruthFormat::kKittiOxts && format != TruthFormat::kNdt) {
    Throw("{}: --truth-lever-arm applies to kitti_oxts and ndt ground truth only, not {}", path,
          TruthFormatName(format));
  }
  PositionTrack track;
  switch (format) {
    case TruthFormat::kDrive: {
      Drive drive = LoadDrive(path);
      if (!drive.ground_truth || drive.ground_truth->samples.empty()) {
        Throw("{}: the drive has no ground truth", (fs::path(path) / "drive.json").string());
      }
      track = std::move(*drive.ground_truth);
      break;
    }
    case TruthFormat::kKittiOxts:
      track = ReadKittiOxtsTruth(path, options);
      break;
    case TruthFormat::kTum:
      track = ReadTumTruth(path, options);
      break;
    case TruthFormat::kKittiPoses:
      track = ReadKittiPosesTruth(path, options);
      break;
    case TruthFormat::kNdt:
      track = ReadNdtTruth(path, options);
      break;
    case TruthFormat::kCsv:
      track = ReadPositionCsv(path, options.origin);
      break;
    case TruthFormat::kAuto:
      break;
  }
  if (track.samples.empty()) Throw("{}: the ground truth has no positions", path);
  return track;
}

}  // namespace epiloc
