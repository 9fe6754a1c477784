#include "epiloc/eval/export.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/eval/truth.h"

namespace epiloc {
namespace fs = std::filesystem;
namespace {

const std::vector<std::string> kFormatNames = {"tum", "kitti", "geojson", "kml", "gpx"};

// The ok rows of one method, by time.
std::vector<const ResultRow*> OkRows(const ResultTable& table, const std::string& method) {
  std::vector<const ResultRow*> rows;
  for (const auto& row : table.rows) {
    if (row.method == method && row.status == ResultStatus::kOk && row.has_position) {
      rows.push_back(&row);
    }
  }
  std::stable_sort(rows.begin(), rows.end(), [](const ResultRow* a, const ResultRow* b) {
    return a->timestamp_s < b->timestamp_s;
  });
  return rows;
}

// enu_from_cam of each row in the origin's ENU axes (see the header).
std::vector<Eigen::Matrix3d> Orientations(const std::vector<const ResultRow*>& rows,
                                          const std::vector<Eigen::Vector3d>& points,
                                          const EnuFrame& enu) {
  std::vector<Eigen::Matrix3d> rotations;
  Eigen::Vector2d last_direction(0.0, 1.0);  // north until the track moves
  for (size_t i = 0; i < rows.size(); ++i) {
    if (rows[i]->enu_from_cam) {
      rotations.push_back(enu.EnuFromLocalEnu(rows[i]->position) *
                          rows[i]->enu_from_cam->toRotationMatrix());
      continue;
    }
    const size_t before = i > 0 ? i - 1 : i;
    const size_t after = i + 1 < rows.size() ? i + 1 : i;
    const Eigen::Vector2d d = (points[after] - points[before]).head<2>();
    if (d.norm() > 1e-6) last_direction = d.normalized();
    const Eigen::Vector3d forward(last_direction.x(), last_direction.y(), 0.0);
    const Eigen::Vector3d right(last_direction.y(), -last_direction.x(), 0.0);
    Eigen::Matrix3d r;
    r.col(0) = right;
    r.col(1) = -Eigen::Vector3d::UnitZ();
    r.col(2) = forward;
    rotations.push_back(r);
  }
  return rotations;
}

// Written under a temporary name and renamed by CloseOut: a failure leaves no partial file.
AtomicOfstream OpenOut(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  std::error_code error;
  if (!parent.empty()) fs::create_directories(parent, error);
  return AtomicOfstream(path);
}

void CloseOut(AtomicOfstream& out, const std::string& path) { out.Commit(); }

std::string XmlEscape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '&') {
      out += "&amp;";
    } else if (c == '<') {
      out += "&lt;";
    } else if (c == '>') {
      out += "&gt;";
    } else {
      out += c;
    }
  }
  return out;
}

void WritePoses(const ResultTable& table,
                const std::string& method,
                const ExportOptions& options,
                const std::string& path,
                ExportSummary& summary) {
  const auto rows = OkRows(table, method);
  summary.origin = options.origin ? *options.origin : rows.front()->position;
  const EnuFrame enu(summary.origin);
  std::vector<Eigen::Vector3d> points;
  for (const auto* row : rows) points.push_back(enu.ToEnu(row->position));
  const auto rotations = Orientations(rows, points, enu);
  auto out = OpenOut(path);
  if (options.format == TrajectoryFormat::kTum) {
    out << "# epiloc export: t x y z qx qy qz qw, ENU metres about "
        << FormatDouble(summary.origin.lat_deg) << "," << FormatDouble(summary.origin.lon_deg)
        << "," << FormatDouble(summary.origin.alt_m) << ", method " << method << "\n";
    for (size_t i = 0; i < rows.size(); ++i) {
      const Eigen::Quaterniond q(rotations[i]);
      out << fmt::format("{} {} {} {} {} {} {} {}\n", FormatDouble(rows[i]->timestamp_s),
                         FormatDouble(points[i].x()), FormatDouble(points[i].y()),
                         FormatDouble(points[i].z()), FormatDouble(q.x()), FormatDouble(q.y()),
                         FormatDouble(q.z()), FormatDouble(q.w()));
    }
  } else {
    const Eigen::Matrix3d world_from_enu = ZUpFromCameraAxes().transpose();
    fs::path times(path);
    times.replace_extension();
    times += "_times.txt";
    summary.times_path = times.string();
    auto times_out = OpenOut(summary.times_path);
    for (size_t i = 0; i < rows.size(); ++i) {
      const Eigen::Matrix3d r = world_from_enu * rotations[i];
      const Eigen::Vector3d t = world_from_enu * points[i];
      std::vector<std::string> numbers;
      for (int k = 0; k < 3; ++k) {
        for (int c = 0; c < 3; ++c) numbers.push_back(FormatDouble(r(k, c) + 0.0));  // no "-0"
        numbers.push_back(FormatDouble(t(k) + 0.0));
      }
      out << fmt::format("{}\n", fmt::join(numbers, " "));
      times_out << FormatDouble(rows[i]->timestamp_s) << "\n";
    }
    CloseOut(times_out, summary.times_path);
  }
  CloseOut(out, path);
  summary.rows = static_cast<int64_t>(rows.size());
}

void WriteGeoJson(const ResultTable& table,
                  const std::vector<std::string>& methods,
                  const std::string& path,
                  ExportSummary& summary) {
  nlohmann::json features = nlohmann::json::array();
  for (const auto& method : methods) {
    const auto rows = OkRows(table, method);
    nlohmann::json line = nlohmann::json::array();
    for (const auto* row : rows) {
      line.push_back({row->position.lon_deg, row->position.lat_deg, row->position.alt_m});
    }
    if (rows.size() >= 2) {
      features.push_back(
          {{"type", "Feature"},
           {"geometry", {{"type", "LineString"}, {"coordinates", line}}},
           {"properties", {{"method", method}, {"kind", "track"}, {"frames", rows.size()}}}});
    }
    for (size_t i = 0; i < rows.size(); ++i) {
      const ResultRow& row = *rows[i];
      nlohmann::json properties = {
          {"method", method},
          {"kind", "frame"},
          {"frame",
           row.frame == kInvalidFrame ? nlohmann::json(nullptr) : nlohmann::json(row.frame)},
          {"timestamp_s", row.timestamp_s},
          {"status", StatusName(row.status)},
          {"s_m", row.has_s ? nlohmann::json(row.s_m) : nlohmann::json(nullptr)},
          {"db_frame",
           row.db_frame == kInvalidImage ? nlohmann::json(nullptr) : nlohmann::json(row.db_frame)}};
      for (size_t c = 0; c < table.extra_columns.size(); ++c) {
        properties[table.extra_columns[c]] = row.extra[c];
      }
      features.push_back({{"type", "Feature"},
                          {"geometry", {{"type", "Point"}, {"coordinates", line[i]}}},
                          {"properties", properties}});
    }
    summary.rows += static_cast<int64_t>(rows.size());
  }
  const nlohmann::json collection = {{"type", "FeatureCollection"}, {"features", features}};
  auto out = OpenOut(path);
  out << collection.dump(1) << "\n";
  CloseOut(out, path);
}

std::string Coordinates(const ResultRow& row) {
  return fmt::format("{:.9f},{:.9f},{:.3f}", row.position.lon_deg, row.position.lat_deg,
                     row.position.alt_m);
}

void WriteKml(const ResultTable& table,
              const std::vector<std::string>& methods,
              const std::string& path,
              ExportSummary& summary) {
  // KML colours are aabbggrr.
  const std::vector<std::string> colours = {"ff2827d6", "ffb4771f", "ff2ca02c", "ff0e7fff",
                                            "ffbd6794", "ff4b568c", "ffc277e3"};
  auto out = OpenOut(path);
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n"
      << "<name>" << XmlEscape(fs::path(table.path).filename().string()) << "</name>\n";
  for (size_t m = 0; m < methods.size(); ++m) {
    out << fmt::format(
        "<Style id=\"{}\"><LineStyle><color>{}</color><width>3</width></LineStyle>"
        "</Style>\n",
        methods[m], colours[m % colours.size()]);
  }
  for (const auto& method : methods) {
    const auto rows = OkRows(table, method);
    out << "<Placemark><name>" << method << "</name><styleUrl>#" << method
        << "</styleUrl><LineString><tessellate>1</tessellate><coordinates>\n";
    for (const auto* row : rows) out << Coordinates(*row) << "\n";
    out << "</coordinates></LineString></Placemark>\n<Folder><name>" << method
        << " frames</name>\n";
    for (const auto* row : rows) {
      out << "<Placemark><name>" << (row->frame == kInvalidFrame ? "" : std::to_string(row->frame))
          << "</name>";
      if (const auto time = IsoTimeOfUnixSeconds(row->timestamp_s)) {
        out << "<TimeStamp><when>" << *time << "</when></TimeStamp>";
      }
      out << "<Point><coordinates>" << Coordinates(*row) << "</coordinates></Point></Placemark>\n";
    }
    out << "</Folder>\n";
    summary.rows += static_cast<int64_t>(rows.size());
  }
  out << "</Document>\n</kml>\n";
  CloseOut(out, path);
}

void WriteGpx(const ResultTable& table,
              const std::vector<std::string>& methods,
              const std::string& path,
              ExportSummary& summary) {
  auto out = OpenOut(path);
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<gpx version=\"1.1\" creator=\"epiloc\" xmlns=\"http://www.topografix.com/GPX/1/1\">\n";
  for (const auto& method : methods) {
    const auto rows = OkRows(table, method);
    out << "<trk><name>" << method << "</name><trkseg>\n";
    for (const auto* row : rows) {
      out << fmt::format("<trkpt lat=\"{:.9f}\" lon=\"{:.9f}\"><ele>{:.3f}</ele>",
                         row->position.lat_deg, row->position.lon_deg, row->position.alt_m);
      if (const auto time = IsoTimeOfUnixSeconds(row->timestamp_s)) {
        out << "<time>" << *time << "</time>";
      }
      out << "</trkpt>\n";
    }
    out << "</trkseg></trk>\n";
    summary.rows += static_cast<int64_t>(rows.size());
  }
  out << "</gpx>\n";
  CloseOut(out, path);
}

}  // namespace

TrajectoryFormat ParseTrajectoryFormat(const std::string& name) {
  for (size_t i = 0; i < kFormatNames.size(); ++i) {
    if (kFormatNames[i] == name) return static_cast<TrajectoryFormat>(i);
  }
  Throw("unknown export format '{}' (known: {})", name, fmt::join(kFormatNames, ", "));
}

std::string TrajectoryFormatName(TrajectoryFormat format) {
  return kFormatNames[static_cast<size_t>(format)];
}

std::optional<std::string> IsoTimeOfUnixSeconds(double timestamp_s) {
  constexpr double kFirst = 94694400.0;   // 1973-01-01
  constexpr double kLast = 4102444800.0;  // 2100-01-01
  if (!(timestamp_s >= kFirst && timestamp_s < kLast)) return std::nullopt;
  int64_t millis = static_cast<int64_t>(std::llround(timestamp_s * 1000.0));
  const std::time_t seconds = static_cast<std::time_t>(millis / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", utc.tm_year + 1900,
                     utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec,
                     millis % 1000);
}

ExportSummary ExportTrajectory(const ResultTable& table,
                               const ExportOptions& options,
                               const std::string& out_path) {
  if (options.origin) CheckGeodetic(*options.origin, "--origin");
  const std::vector<std::string> present = table.Methods();
  std::vector<std::string> methods = present;
  if (!options.method.empty()) {
    if (std::find(present.begin(), present.end(), options.method) == present.end()) {
      Throw("{}: no rows of method '{}' (the file has: {})", table.path, options.method,
            fmt::join(present, ", "));
    }
    methods = {options.method};
  }
  const bool poses =
      options.format == TrajectoryFormat::kTum || options.format == TrajectoryFormat::kKitti;
  if (poses && methods.size() > 1) {
    Throw("{}: {} holds one trajectory but the file has methods {}; choose one with --method",
          table.path, TrajectoryFormatName(options.format), fmt::join(methods, ", "));
  }
  for (const auto& method : methods) {
    if (OkRows(table, method).empty()) {
      Throw("{}: method '{}' has no rows with status ok to export", table.path, method);
    }
  }
  ExportSummary summary;
  summary.methods = methods;
  switch (options.format) {
    case TrajectoryFormat::kTum:
    case TrajectoryFormat::kKitti:
      WritePoses(table, methods.front(), options, out_path, summary);
      break;
    case TrajectoryFormat::kGeoJson:
      WriteGeoJson(table, methods, out_path, summary);
      break;
    case TrajectoryFormat::kKml:
      WriteKml(table, methods, out_path, summary);
      break;
    case TrajectoryFormat::kGpx:
      WriteGpx(table, methods, out_path, summary);
      break;
  }
  return summary;
}

}  // namespace epiloc
