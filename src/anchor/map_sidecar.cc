#include "epiloc/anchor/map_sidecar.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/db/database.h"

namespace epiloc {
namespace {

using Json = nlohmann::json;
constexpr int kSidecarVersion = 1;

Json GeodeticJson(const Geodetic& g) {
  return {{"lat_deg", g.lat_deg}, {"lon_deg", g.lon_deg}, {"alt_m", g.alt_m}};
}

Json VectorJson(const Eigen::Vector3f& v) { return Json::array({v.x(), v.y(), v.z()}); }

// Checked access to the sidecar's keys: every message names the file and the key.
class Reader {
 public:
  explicit Reader(std::string path) : path_(std::move(path)) {}

  const Json& At(const Json& object, const std::string& key) const {
    if (!object.contains(key)) Throw("{}: missing key '{}'", path_, key);
    return object.at(key);
  }
  double Number(const Json& object, const std::string& key) const {
    const Json& value = At(object, key);
    if (!value.is_number() || !std::isfinite(value.get<double>())) {
      Throw("{}: '{}' must be a finite number", path_, key);
    }
    return value.get<double>();
  }
  std::string String(const Json& object, const std::string& key) const {
    if (!object.contains(key)) return "";
    const Json& value = object.at(key);
    if (!value.is_string()) Throw("{}: '{}' must be a string", path_, key);
    return value.get<std::string>();
  }
  int64_t Integer(const Json& object, const std::string& key) const {
    if (!object.contains(key)) return 0;
    const Json& value = object.at(key);
    if (!value.is_number_integer()) Throw("{}: '{}' must be an integer", path_, key);
    return value.get<int64_t>();
  }
  Eigen::Vector3f Vector(const Json& object, const std::string& key) const {
    const Json& value = At(object, key);
    if (!value.is_array() || value.size() != 3 || !value[0].is_number() ||
        !value[1].is_number() || !value[2].is_number()) {
      Throw("{}: '{}' must be an array of 3 numbers", path_, key);
    }
    return Eigen::Vector3f(value[0].get<float>(), value[1].get<float>(), value[2].get<float>());
  }

 private:
  std::string path_;
};

double OriginDistanceM(const Geodetic& a, const Geodetic& b) {
  return EnuFrame(a).ToEnu(b).norm();
}

std::string FormatGeodetic(const Geodetic& g) {
  return fmt::format("{:.9f},{:.9f},{:.3f}", g.lat_deg, g.lon_deg, g.alt_m);
}

}  // namespace

std::string SidecarPath(const std::string& cloud_path) {
  std::string path = cloud_path;
  while (path.size() > 1 && path.back() == '/') path.pop_back();
  return path + ".json";
}

MapSidecar DescribeCloud(const PointCloud& cloud,
                         const Geodetic& enu_origin,
                         const std::string& origin_source) {
  MapSidecar sidecar;
  sidecar.enu_origin = enu_origin;
  sidecar.origin_source = origin_source;
  sidecar.num_points = static_cast<int64_t>(cloud.size());
  if (cloud.HasIntensity()) sidecar.attributes.push_back("intensity");
  if (cloud.HasColour()) sidecar.attributes.push_back("rgb");
  sidecar.bounds = ComputeBounds(cloud);
  sidecar.created_by = std::string("epiloc ") + EPILOC_VERSION;
  return sidecar;
}

void WriteMapSidecar(const MapSidecar& sidecar, const std::string& path) {
  Json json = {{"format", "epiloc-map"},
               {"version", kSidecarVersion},
               {"enu_origin", GeodeticJson(sidecar.enu_origin)},
               {"origin_source", sidecar.origin_source},
               {"source_drive", sidecar.source_drive},
               {"source_dir", sidecar.source_dir},
               {"voxel_m", sidecar.voxel_m},
               {"num_points", sidecar.num_points},
               {"num_scans", sidecar.num_scans},
               {"attributes", sidecar.attributes},
               {"created_by", sidecar.created_by}};
  if (!sidecar.colour_mode.empty()) {
    json["colour"] = {{"mode", sidecar.colour_mode},
                      {"frames", sidecar.colour_frames},
                      {"coloured_points", sidecar.coloured_points}};
  }
  if (!sidecar.bounds.Empty()) {
    json["bounds"] = {{"min", VectorJson(sidecar.bounds.min)},
                      {"max", VectorJson(sidecar.bounds.max)}};
  }
  AtomicOfstream out(path);
  out << json.dump(2) << "\n";  // doubles round-trip exactly
  out.Commit();
}

MapSidecar ReadMapSidecar(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open the map sidecar", path);
  Json json;
  try {
    json = Json::parse(in);
  } catch (const Json::exception& e) {
    Throw("{}: not a JSON map sidecar: {}", path, e.what());
  }
  if (!json.is_object()) Throw("{}: the map sidecar must be a JSON object", path);
  static const std::set<std::string> kKeys = {
      "format",     "version",    "enu_origin", "origin_source", "source_drive",
      "source_dir", "voxel_m",    "num_points", "num_scans",     "attributes",
      "colour",     "bounds",     "created_by"};
  for (const auto& item : json.items()) {
    if (kKeys.count(item.key()) == 0) Throw("{}: unknown key '{}'", path, item.key());
  }
  const Reader r(path);
  if (r.String(json, "format") != "epiloc-map") {
    Throw("{}: not an epiloc map sidecar (\"format\" must be \"epiloc-map\")", path);
  }
  if (r.Integer(json, "version") != kSidecarVersion) {
    Throw("{}: map sidecar version {} not supported (this build reads version {})", path,
          r.Integer(json, "version"), kSidecarVersion);
  }
  MapSidecar s;
  const Json& origin = r.At(json, "enu_origin");
  if (!origin.is_object()) Throw("{}: 'enu_origin' must be an object", path);
  s.enu_origin = {r.Number(origin, "lat_deg"), r.Number(origin, "lon_deg"),
                  r.Number(origin, "alt_m")};
  CheckGeodetic(s.enu_origin, path + ": enu_origin");
  s.origin_source = r.String(json, "origin_source");
  s.source_drive = r.String(json, "source_drive");
  s.source_dir = r.String(json, "source_dir");
  s.voxel_m = json.contains("voxel_m") ? r.Number(json, "voxel_m") : 0.0;
  s.num_points = r.Integer(json, "num_points");
  s.num_scans = r.Integer(json, "num_scans");
  if (json.contains("attributes")) {
    const Json& a = json.at("attributes");
    if (!a.is_array()) Throw("{}: 'attributes' must be an array of strings", path);
    for (const Json& name : a) {
      if (!name.is_string()) Throw("{}: 'attributes' must be an array of strings", path);
      s.attributes.push_back(name.get<std::string>());
    }
  }
  if (json.contains("colour")) {
    const Json& c = json.at("colour");
    if (!c.is_object()) Throw("{}: 'colour' must be an object", path);
    s.colour_mode = r.String(c, "mode");
    s.colour_frames = r.Integer(c, "frames");
    s.coloured_points = r.Integer(c, "coloured_points");
  }
  if (json.contains("bounds")) {
    const Json& b = json.at("bounds");
    if (!b.is_object()) Throw("{}: 'bounds' must be an object", path);
    s.bounds.min = r.Vector(b, "min");
    s.bounds.max = r.Vector(b, "max");
  }
  s.created_by = r.String(json, "created_by");
  return s;
}

std::optional<MapSidecar> FindMapSidecar(const std::string& cloud_path) {
  const std::string path = SidecarPath(cloud_path);
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return std::nullopt;
  return ReadMapSidecar(path);
}

Geodetic ParseGeodetic(const std::string& text, const std::string& option_name) {
  std::stringstream stream(text);
  std::string part;
  std::vector<double> values;
  while (std::getline(stream, part, ',')) {
    try {
      size_t used = 0;
      values.push_back(std::stod(part, &used));
      while (used < part.size() && std::isspace(static_cast<unsigned char>(part[used]))) ++used;
      if (used != part.size()) values.push_back(NAN);
    } catch (const std::exception&) {
      values.push_back(NAN);
    }
  }
  if (values.size() != 3 || !std::isfinite(values[0]) || !std::isfinite(values[1]) ||
      !std::isfinite(values[2])) {
    Throw("{} '{}': expected LAT,LON,ALT (degrees, degrees, metres)", option_name, text);
  }
  const Geodetic g{values[0], values[1], values[2]};
  CheckGeodetic(g, fmt::format("{} '{}'", option_name, text));
  return g;
}

Geodetic DatabaseEnuOrigin(const std::string& db_path) {
  const Database db(db_path, Database::Mode::kReadOnly);
  const auto origin = db.EnuOrigin();
  if (!origin) Throw("{}: the database has no ENU origin yet (build it with build-db)", db_path);
  return *origin;
}

MapOrigin ResolveMapOrigin(const MapOriginInputs& inputs) {
  MapOrigin result;
  result.sidecar = FindMapSidecar(inputs.cloud_path);
  std::optional<Geodetic> db_origin;
  if (!inputs.db_path.empty()) db_origin = DatabaseEnuOrigin(inputs.db_path);

  std::vector<std::pair<std::string, Geodetic>> sources;
  if (inputs.explicit_origin) sources.emplace_back("--cloud-origin", *inputs.explicit_origin);
  if (result.sidecar) {
    sources.emplace_back("sidecar " + SidecarPath(inputs.cloud_path), result.sidecar->enu_origin);
  }
  if (db_origin) sources.emplace_back("database " + inputs.db_path, *db_origin);
  if (sources.empty()) {
    Throw("{}: no sidecar {}; give --cloud-origin LAT,LON,ALT or --db ROUTE.sqlite",
          inputs.cloud_path, SidecarPath(inputs.cloud_path));
  }
  result.source = sources.front().first;
  result.enu_origin = sources.front().second;
  for (size_t i = 1; i < sources.size(); ++i) {
    const double d = OriginDistanceM(result.enu_origin, sources[i].second);
    if (d > 1e-3) {
      spdlog::warn("{}: origin {} from {} differs by {:.3f} m from {} of {}; using the former",
                   inputs.cloud_path, FormatGeodetic(result.enu_origin), result.source, d,
                   FormatGeodetic(sources[i].second), sources[i].first);
    }
  }
  return result;
}

}  // namespace epiloc
