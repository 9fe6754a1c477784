#include "epiloc/io/drive.h"

#include <filesystem>
#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/io/position_readers.h"
#include "io_internal.h"

namespace epiloc {
namespace {

using Json = nlohmann::json;
constexpr int kDriveFormatVersion = 1;

// A JSON object of the manifest whose keys are all known; typed getters name the file and key.
class JsonObject {
 public:
  JsonObject(const Json& json,
             const std::string& file,
             const std::string& prefix,
             const std::set<std::string>& allowed)
      : json_(json), file_(file), prefix_(prefix) {
    if (!json.is_object()) {
      Throw("{}: {} must be a JSON object", file, prefix.empty() ? "the manifest" : Key(""));
    }
    for (const auto& item : json.items()) {
      if (allowed.count(item.key()) == 0) Throw("{}: unknown key '{}'", file, Key(item.key()));
    }
  }

  bool Has(const std::string& key) const { return json_.contains(key); }
  const Json& At(const std::string& key) const {
    if (!Has(key)) Throw("{}: missing key '{}'", file_, Key(key));
    return json_.at(key);
  }
  double Number(const std::string& key) const {
    const Json& value = At(key);
    if (!value.is_number()) Throw("{}: '{}' must be a number", file_, Key(key));
    return value.get<double>();
  }
  double Number(const std::string& key, double default_value) const {
    return Has(key) ? Number(key) : default_value;
  }
  int64_t Integer(const std::string& key) const {
    const Json& value = At(key);
    if (!value.is_number_integer()) Throw("{}: '{}' must be an integer", file_, Key(key));
    return value.get<int64_t>();
  }
  std::string String(const std::string& key) const {
    const Json& value = At(key);
    if (!value.is_string() || value.get<std::string>().empty()) {
      Throw("{}: '{}' must be a non-empty string", file_, Key(key));
    }
    return value.get<std::string>();
  }
  std::string String(const std::string& key, const std::string& default_value) const {
    return Has(key) ? String(key) : default_value;
  }
  bool Bool(const std::string& key, bool default_value) const {
    if (!Has(key)) return default_value;
    if (!json_.at(key).is_boolean()) Throw("{}: '{}' must be true or false", file_, Key(key));
    return json_.at(key).get<bool>();
  }
  std::string Key(const std::string& key) const {
    return prefix_.empty() ? key : key.empty() ? prefix_ : prefix_ + "." + key;
  }

 private:
  const Json& json_;
  std::string file_;
  std::string prefix_;
};

Camera ReadCamera(const JsonObject& manifest, const std::string& file, bool* colour) {
  const JsonObject c(manifest.At("camera"), file, "camera",
                     {"width", "height", "fx", "fy", "cx", "cy", "distortion", "colour"});
  Camera camera;
  camera.width = static_cast<int>(c.Integer("width"));
  camera.height = static_cast<int>(c.Integer("height"));
  camera.fx = c.Number("fx");
  camera.fy = c.Number("fy");
  camera.cx = c.Number("cx");
  camera.cy = c.Number("cy");
  if (c.Has("distortion")) {
    const Json& d = c.At("distortion");
    if (!d.is_array() || d.size() != 5) {
      Throw("{}: 'camera.distortion' must be an array of 5 numbers [k1, k2, p1, p2, k3]", file);
    }
    for (size_t i = 0; i < 5; ++i) {
      if (!d[i].is_number()) Throw("{}: 'camera.distortion' must hold numbers", file);
      camera.distortion[i] = d[i].get<double>();
    }
  }
  *colour = c.Bool("colour", false);
  camera.Check(file + ": camera");
  return camera;
}

std::vector<FrameRecord> ReadFrames(const JsonObject& manifest,
                                    Drive* drive,
                                    const std::string& file) {
  const JsonObject f(manifest.At("frames"), file, "frames",
                     {"csv", "folder", "video", "timestamps", "fps", "start_s"});
  const int num_sources = f.Has("csv") + f.Has("folder") + f.Has("video");
  const bool video = f.Has("video");
  if (num_sources == 0) Throw("{}: 'frames' needs one of \"csv\", \"folder\", \"video\"", file);
  if (f.Has("folder") && num_sources > 1) {
    Throw("{}: 'frames' has \"folder\" together with \"csv\" or \"video\"", file);
  }
  const bool has_times = f.Has("timestamps"), has_fps = f.Has("fps");
  if (f.Has("csv") && (has_times || has_fps || f.Has("start_s"))) {
    Throw(
        "{}: frames from \"csv\" take their times from the CSV, not from \"timestamps\", \"fps\" "
        "or \"start_s\"",
        file);
  }
  if (has_times && has_fps) Throw("{}: 'frames' has both \"timestamps\" and \"fps\"", file);
  if (has_times && f.Has("start_s"))
    Throw("{}: \"start_s\" does not apply to \"timestamps\"", file);
  const double fps = f.Number("fps", 0.0);
  if (has_fps && !(fps > 0)) Throw("{}: 'frames.fps' must be positive", file);
  const double start_s = f.Number("start_s", 0.0);
  const std::string timestamps = has_times ? ResolvePath(drive->dir, f.String("timestamps")) : "";

  std::vector<FrameRecord> frames;
  std::string where;
  if (video) {
    drive->video = f.String("video");
    if (f.Has("csv")) {
      where = ResolvePath(drive->dir, f.String("csv"));
      frames = ReadFramesCsv(where, drive->dir, true);
      if (!FileExists(drive->VideoPath())) Throw("{}: video file not found", drive->VideoPath());
    } else {
      where = has_times ? timestamps : drive->VideoPath();
      frames = ReadFramesVideo(drive->VideoPath(), timestamps, fps, start_s);
    }
  } else if (f.Has("csv")) {
    where = ResolvePath(drive->dir, f.String("csv"));
    frames = ReadFramesCsv(where, drive->dir, false);
  } else {
    if (!has_times && !has_fps) {
      Throw("{}: frames from a \"folder\" need \"timestamps\" or \"fps\"", file);
    }
    const std::string folder = f.String("folder");
    where = has_times ? timestamps : ResolvePath(drive->dir, folder);
    frames = ReadFramesFolder(ResolvePath(drive->dir, folder), folder, timestamps, fps, start_s);
  }
  if (frames.empty()) Throw("{}: no frames", where);
  CheckFrameOrder(frames, where);
  return frames;
}

PositionTrack ReadTrack(const JsonObject& manifest,
                        const std::string& key,
                        const Drive& drive,
                        const std::optional<Geodetic>& origin,
                        double time_offset_s,
                        const std::string& file) {
  const JsonObject p(manifest.At(key), file, key, {"file", "format", "date"});
  const PositionFormat format = ParsePositionFormat(p.String("format", "csv"), file + ": " + key);
  if (p.Has("date") && format != PositionFormat::kNmea) {
    Throw("{}: '{}.date' applies to the nmea format only", file, key);
  }
  PositionTrack track =
      ReadPositions(ResolvePath(drive.dir, p.String("file")), format, origin, p.String("date", ""));
  for (auto& sample : track.samples) sample.timestamp_s += time_offset_s;
  return track;
}

Json CameraJson(const Camera& camera, bool colour) {
  return Json{{"width", camera.width},
              {"height", camera.height},
              {"fx", camera.fx},
              {"fy", camera.fy},
              {"cx", camera.cx},
              {"cy", camera.cy},
              {"distortion", camera.distortion},
              {"colour", colour}};
}

}  // namespace

Drive LoadDrive(const std::string& dir) {
  const std::string file = (std::filesystem::path(dir) / "drive.json").string();
  std::ifstream in(file);
  if (!in) Throw("{}: cannot open the drive manifest", file);
  Json json;
  try {
    json = Json::parse(in);
  } catch (const Json::exception& e) {
    Throw("{}: malformed JSON: {}", file, e.what());
  }
  const JsonObject manifest(json, file, "",
                            {"epiloc_drive", "name", "camera", "frames", "gnss", "ground_truth",
                             "origin", "lidar", "max_gap_s", "time_offset_s"});
  const int64_t version = manifest.Integer("epiloc_drive");
  if (version != kDriveFormatVersion) {
    Throw("{}: drive format version {} is not supported (this epiloc reads {})", file, version,
          kDriveFormatVersion);
  }
  Drive drive;
  drive.dir = dir;
  drive.name = manifest.String("name");
  drive.camera = ReadCamera(manifest, file, &drive.colour);
  drive.max_gap_s = manifest.Number("max_gap_s", drive.max_gap_s);
  if (!(drive.max_gap_s > 0)) Throw("{}: 'max_gap_s' must be positive", file);
  const double time_offset_s = manifest.Number("time_offset_s", 0.0);

  std::optional<Geodetic> origin;
  if (manifest.Has("origin")) {
    const JsonObject o(manifest.At("origin"), file, "origin", {"lat_deg", "lon_deg", "alt_m"});
    origin = Geodetic{o.Number("lat_deg"), o.Number("lon_deg"), o.Number("alt_m", 0.0)};
    CheckGeodetic(*origin, file + ": origin");
  }

  drive.frames = ReadFrames(manifest, &drive, file);
  // Reading the first frame checks that the images fit the calibration.
  FrameReader(drive).ReadGrey(0);

  if (manifest.Has("gnss")) {
    drive.gnss = ReadTrack(manifest, "gnss", drive, origin, time_offset_s, file);
  }
  if (manifest.Has("ground_truth")) {
    drive.ground_truth = ReadTrack(manifest, "ground_truth", drive, origin, time_offset_s, file);
  }
  if (manifest.Has("lidar")) {
    const JsonObject l(manifest.At("lidar"), file, "lidar", {"csv"});
    drive.lidar = ReadLidarCsv(ResolvePath(dir, l.String("csv")), dir);
  }
  return drive;
}

void WriteDrive(const Drive& drive, const std::string& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) Throw("{}: cannot create directory: {}", dir, error.message());
  // Relative paths stay valid only in the drive's own directory.
  const bool same_dir = drive.dir.empty() || std::filesystem::equivalent(drive.dir, dir, error);
  const auto path_for = [&](const std::string& path) {
    if (same_dir || path.empty() || std::filesystem::path(path).is_absolute()) return path;
    return std::filesystem::absolute(ResolvePath(drive.dir, path)).lexically_normal().string();
  };

  Json manifest = {{"epiloc_drive", kDriveFormatVersion},
                   {"name", drive.name},
                   {"camera", CameraJson(drive.camera, drive.colour)},
                   {"max_gap_s", drive.max_gap_s}};
  manifest["frames"] = {{"csv", "frames.csv"}};
  if (!drive.video.empty()) manifest["frames"]["video"] = path_for(drive.video);
  {
    CsvWriter csv((std::filesystem::path(dir) / "frames.csv").string(),
                  {"frame", "timestamp_s", "image"});
    for (const auto& f : drive.frames) {
      csv.WriteRow({std::to_string(f.frame), FormatDouble(f.timestamp_s), path_for(f.image)});
    }
    csv.Close();
  }
  if (!drive.gnss.samples.empty()) {
    WritePositionCsv(drive.gnss, (std::filesystem::path(dir) / "gnss.csv").string());
    manifest["gnss"] = {{"file", "gnss.csv"}, {"format", "csv"}};
  }
  if (drive.ground_truth) {
    WritePositionCsv(*drive.ground_truth,
                     (std::filesystem::path(dir) / "ground_truth.csv").string());
    manifest["ground_truth"] = {{"file", "ground_truth.csv"}, {"format", "csv"}};
  }
  if (!drive.lidar.empty()) {
    std::vector<LidarScan> scans = drive.lidar;
    for (auto& scan : scans) scan.path = path_for(scan.path);
    WriteLidarCsv(scans, (std::filesystem::path(dir) / "lidar.csv").string());
    manifest["lidar"] = {{"csv", "lidar.csv"}};
  }
  const std::string file = (std::filesystem::path(dir) / "drive.json").string();
  std::ofstream out(file);
  out << manifest.dump(2) << '\n';
  out.close();
  if (!out) Throw("{}: write failed", file);
}

}  // namespace epiloc
