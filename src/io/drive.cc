#include "epiloc/io/drive.h"
#include "epiloc/io/drive_follower.h"

#include <filesystem>
#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
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
  // Range-checked before the narrowing: 4294967297 must not become 1.
  for (const char* key : {"width", "height"}) {
    const int64_t side = c.Integer(key);
    if (side <= 0 || side >= Camera::kMaxImageSide) {
      Throw("{}: 'camera.{}' = {} must be in [1, {})", file, key, side, Camera::kMaxImageSide);
    }
  }
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
      drive->frames_csv = where;
      frames = ReadFramesCsv(where, drive->dir, true);
      const std::string problem = FileProblem(drive->VideoPath());
      if (!problem.empty()) Throw("{}: video file {}", drive->VideoPath(), problem);
    } else {
      where = has_times ? timestamps : drive->VideoPath();
      frames = ReadFramesVideo(drive->VideoPath(), timestamps, fps, start_s);
    }
  } else if (f.Has("csv")) {
    where = ResolvePath(drive->dir, f.String("csv"));
    drive->frames_csv = where;
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

namespace {

const std::set<std::string> kManifestKeys = {"epiloc_drive", "name",         "camera", "frames",
                                             "gnss",         "ground_truth", "origin", "lidar",
                                             "max_gap_s",    "time_offset_s"};

// drive.json parsed, without reading the files it refers to.
struct Manifest {
  std::string file;
  Json json;
  Drive drive;  // dir, name, camera, colour, max_gap_s
  std::optional<Geodetic> origin;
  double time_offset_s = 0.0;
};

// A drive.json-style file parsed, with a key given twice in one object refused: nlohmann keeps
// the last one without a word, so `"fx": 600, "fx": 700` calibrated with 700.
Json ParseJsonFile(std::istream& in, const std::string& file) {
  std::vector<std::set<std::string>> keys;  // the keys seen in each open object
  const Json::parser_callback_t callback = [&](int /*depth*/, Json::parse_event_t event,
                                               Json& parsed) {
    if (event == Json::parse_event_t::object_start) {
      keys.emplace_back();
    } else if (event == Json::parse_event_t::object_end) {
      if (!keys.empty()) keys.pop_back();
    } else if (event == Json::parse_event_t::key && !keys.empty() && parsed.is_string()) {
      const std::string& key = parsed.get_ref<const std::string&>();
      if (!keys.back().insert(key).second) {
        Throw("{}: key '{}' is given twice in one object", file, Printable(key));
      }
    }
    return true;
  };
  try {
    // Comments (// and /* */) are accepted: README's annotated example is meant to be copied.
    return Json::parse(in, callback, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const Json::exception& e) {
    Throw("{}: malformed JSON: {}", file, e.what());
  }
}

Manifest ReadManifest(const std::string& dir) {
  Manifest m;
  m.file = (std::filesystem::path(dir) / "drive.json").string();
  const std::string& file = m.file;
  std::ifstream in(file);
  if (!in) Throw("{}: cannot open the drive manifest", file);
  m.json = ParseJsonFile(in, file);
  const JsonObject manifest(m.json, file, "", kManifestKeys);
  const int64_t version = manifest.Integer("epiloc_drive");
  if (version != kDriveFormatVersion) {
    Throw("{}: drive format version {} is not supported (this epiloc reads {})", file, version,
          kDriveFormatVersion);
  }
  Drive& drive = m.drive;
  drive.dir = dir;
  drive.name = manifest.String("name");
  drive.camera = ReadCamera(manifest, file, &drive.colour);
  drive.max_gap_s = manifest.Number("max_gap_s", drive.max_gap_s);
  if (!(drive.max_gap_s > 0)) Throw("{}: 'max_gap_s' must be positive", file);
  m.time_offset_s = manifest.Number("time_offset_s", 0.0);
  if (manifest.Has("origin")) {
    const JsonObject o(manifest.At("origin"), file, "origin", {"lat_deg", "lon_deg", "alt_m"});
    m.origin = Geodetic{o.Number("lat_deg"), o.Number("lon_deg"), o.Number("alt_m", 0.0)};
    CheckGeodetic(*m.origin, file + ": origin");
  }
  return m;
}

}  // namespace

Drive LoadDrive(const std::string& dir) {
  Manifest m = ReadManifest(dir);
  const std::string& file = m.file;
  const JsonObject manifest(m.json, file, "", kManifestKeys);
  Drive drive = std::move(m.drive);
  const std::optional<Geodetic>& origin = m.origin;
  const double time_offset_s = m.time_offset_s;

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

Camera ReadCalibrationFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open the calibration file", path);
  const Json json = ParseJsonFile(in, path);
  if (!json.is_object()) Throw("{}: the calibration file must hold a JSON object", path);
  Json camera_only = Json::object();
  if (json.contains("camera")) camera_only["camera"] = json.at("camera");
  const JsonObject manifest(camera_only, path, "", {"camera"});
  bool colour = false;
  return ReadCamera(manifest, path, &colour);
}

std::vector<std::string> DriveInputPaths(const std::string& dir) {
  const std::string file = (std::filesystem::path(dir) / "drive.json").string();
  std::vector<std::string> paths = {file};
  Json json;
  try {
    std::ifstream in(file);
    if (!in) return paths;
    json = Json::parse(in, nullptr, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const Json::exception&) {
    return paths;
  }
  // Every string value of the sections that name files ("format" and "date" never do).
  std::vector<const Json*> stack;
  for (const char* key : {"frames", "gnss", "ground_truth", "lidar"}) {
    if (json.is_object() && json.contains(key)) stack.push_back(&json.at(key));
  }
  while (!stack.empty()) {
    const Json* node = stack.back();
    stack.pop_back();
    if (node->is_string()) {
      const std::string path = ResolvePath(dir, node->get<std::string>());
      std::error_code error;
      if (std::filesystem::exists(path, error)) paths.push_back(path);
    } else if (node->is_object()) {
      for (const auto& item : node->items()) {
        if (item.key() != "format" && item.key() != "date") stack.push_back(&item.value());
      }
    } else if (node->is_array()) {
      for (const Json& element : *node) stack.push_back(&element);
    }
  }
  // The files the drive's CSVs name: the images of a frames CSV, the scans of a LiDAR CSV (an
  // output must not overwrite a frame's image either). A malformed CSV ends the list: the
  // loader reports it.
  const auto add_column = [&](const char* section, const char* column) {
    if (!json.is_object() || !json.contains(section) || !json.at(section).is_object()) return;
    const Json& entry = json.at(section);
    if (!entry.contains("csv") || !entry.at("csv").is_string()) return;
    try {
      CsvReader csv(ResolvePath(dir, entry.at("csv").get<std::string>()));
      if (!csv.HasColumn(column)) return;
      while (csv.Next()) {
        if (csv.Get(column).empty()) continue;
        const std::string path = ResolvePath(dir, csv.Get(column));
        std::error_code error;
        if (std::filesystem::exists(path, error)) paths.push_back(path);
      }
    } catch (const Error&) {
    }
  };
  add_column("frames", "image");
  add_column("lidar", "path");
  return paths;
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
  AtomicOfstream out(file);
  out << manifest.dump(2) << '\n';
  out.Commit();
}

}  // namespace epiloc

namespace epiloc {

struct DriveFollower::Impl {
  Drive manifest;
  std::string frames_csv;
  std::unique_ptr<FramesCsvRows> frames;
  std::optional<Geodetic> origin;
  double time_offset_s = 0.0;
  std::string gnss_path;
  PositionFormat gnss_format = PositionFormat::kCsv;
  std::string gnss_date;
  std::unique_ptr<PositionCsvRows> gnss_csv;
  std::unique_ptr<NmeaParser> nmea;
  std::ifstream nmea_in;
  int64_t nmea_line = 0;
  PositionTrack gnss;

  void PollGnss();
};

DriveFollower::DriveFollower(const std::string& dir) : impl_(std::make_unique<Impl>()) {
  Manifest m = ReadManifest(dir);
  const JsonObject manifest(m.json, m.file, "", kManifestKeys);
  const JsonObject f(manifest.At("frames"), m.file, "frames",
                     {"csv", "folder", "video", "timestamps", "fps", "start_s"});
  if (!f.Has("csv") || f.Has("video")) {
    Throw("{}: following a growing drive needs its frames in a \"csv\" of image files", m.file);
  }
  impl_->frames_csv = ResolvePath(dir, f.String("csv"));
  if (manifest.Has("gnss")) {
    const JsonObject p(manifest.At("gnss"), m.file, "gnss", {"file", "format", "date"});
    impl_->gnss_format = ParsePositionFormat(p.String("format", "csv"), m.file + ": gnss");
    if (impl_->gnss_format == PositionFormat::kKittiOxts) {
      Throw("{}: a kitti_oxts GNSS folder cannot be followed; use csv or nmea", m.file);
    }
    if (p.Has("date") && impl_->gnss_format != PositionFormat::kNmea) {
      Throw("{}: 'gnss.date' applies to the nmea format only", m.file);
    }
    impl_->gnss_path = ResolvePath(dir, p.String("file"));
    impl_->gnss_date = p.String("date", "");
    impl_->gnss.source = impl_->gnss_path;
  }
  impl_->origin = m.origin;
  impl_->time_offset_s = m.time_offset_s;
  impl_->manifest = std::move(m.drive);
  impl_->manifest.frames_csv = impl_->frames_csv;
}

DriveFollower::~DriveFollower() = default;

const Drive& DriveFollower::manifest() const { return impl_->manifest; }

bool DriveFollower::has_gnss() const { return !impl_->gnss_path.empty(); }

std::vector<FrameRecord> DriveFollower::PollFrames() {
  std::vector<FrameRecord> out;
  if (!impl_->frames) {
    if (!FileExists(impl_->frames_csv)) return out;
    impl_->frames = std::make_unique<FramesCsvRows>(impl_->frames_csv, impl_->manifest.dir, false);
  }
  FrameRecord record;
  while (impl_->frames->Next(&record, true)) out.push_back(record);
  return out;
}

void DriveFollower::Impl::PollGnss() {
  if (gnss_path.empty() || !FileExists(gnss_path)) return;
  PositionSample sample;
  if (gnss_format == PositionFormat::kCsv) {
    if (!gnss_csv) gnss_csv = std::make_unique<PositionCsvRows>(gnss_path, origin);
    while (gnss_csv->Next(&sample, true)) gnss.samples.push_back(sample);
    return;
  }
  if (!nmea) {
    nmea = std::make_unique<NmeaParser>(gnss_path, gnss_date);
    nmea_in.open(gnss_path);
    if (!nmea_in) Throw("{}: cannot open file", gnss_path);
  }
  // Complete lines only; a sentence still being written is read again next time.
  for (;;) {
    nmea_in.clear();
    const std::streampos start = nmea_in.tellg();
    std::string line;
    if (!std::getline(nmea_in, line) || nmea_in.eof()) {
      nmea_in.clear();
      nmea_in.seekg(start);
      return;
    }
    nmea->Feed(line, ++nmea_line, &gnss);
  }
}

std::optional<PositionSample> DriveFollower::GnssAt(double timestamp_s) {
  impl_->PollGnss();
  // The samples are kept in the file's clock; drive.json's time_offset_s maps it to the frames'.
  const double t = timestamp_s - impl_->time_offset_s;
  std::vector<PositionSample>& samples = impl_->gnss.samples;
  // Samples older than the one before t - max_gap can no longer bracket a frame.
  const double horizon = t - 2.0 * impl_->manifest.max_gap_s;
  size_t drop = 0;
  while (drop + 2 < samples.size() && samples[drop + 1].timestamp_s < horizon) ++drop;
  if (drop > 0) samples.erase(samples.begin(), samples.begin() + static_cast<long>(drop));
  std::optional<PositionSample> out = impl_->gnss.Interpolate(t, impl_->manifest.max_gap_s);
  if (out) out->timestamp_s += impl_->time_offset_s;
  return out;
}

}  // namespace epiloc
