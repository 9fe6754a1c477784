#include "epiloc/io/position_readers.h"

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/kitti.h"
#include "io_internal.h"

namespace epiloc {

PositionFormat ParsePositionFormat(const std::string& name, const std::string& where) {
  if (name == "csv") return PositionFormat::kCsv;
  if (name == "nmea") return PositionFormat::kNmea;
  if (name == "kitti_oxts") return PositionFormat::kKittiOxts;
  Throw("{}: unknown position format '{}' (expected csv, nmea or kitti_oxts)", where, name);
}

std::string PositionFormatName(PositionFormat format) {
  switch (format) {
    case PositionFormat::kCsv:
      return "csv";
    case PositionFormat::kNmea:
      return "nmea";
    case PositionFormat::kKittiOxts:
      return "kitti_oxts";
  }
  return "?";
}

PositionTrack ReadPositionCsv(const std::string& path, const std::optional<Geodetic>& origin) {
  CsvReader csv(path);
  csv.RequireColumns({"timestamp_s"});
  const bool geodetic = csv.HasColumn("lat_deg") || csv.HasColumn("lon_deg");
  std::optional<EnuFrame> enu;
  if (geodetic) {
    csv.RequireColumns({"lat_deg", "lon_deg", "alt_m"});
  } else if (csv.HasColumn("x_m") || csv.HasColumn("y_m") || csv.HasColumn("z_m")) {
    csv.RequireColumns({"x_m", "y_m", "z_m"});
    if (!origin) {
      Throw("{}: local x_m,y_m,z_m positions need an \"origin\" in drive.json", path);
    }
    enu.emplace(*origin);
  } else {
    Throw("{}: missing columns lat_deg,lon_deg,alt_m or x_m,y_m,z_m", path);
  }
  const std::vector<std::string> q_columns = {"qw", "qx", "qy", "qz"};
  int num_q = 0;
  for (const auto& c : q_columns) num_q += csv.HasColumn(c) ? 1 : 0;
  if (num_q != 0 && num_q != 4) Throw("{}: needs all of the columns qw,qx,qy,qz or none", path);

  PositionTrack track;
  track.source = path;
  while (csv.Next()) {
    PositionSample sample;
    sample.timestamp_s = csv.GetDouble("timestamp_s");
    if (geodetic) {
      sample.position = {csv.GetDouble("lat_deg"), csv.GetDouble("lon_deg"),
                         csv.GetDouble("alt_m")};
      CheckGeodetic(sample.position, csv.where());
    } else {
      sample.position = enu->ToGeodetic(
          Eigen::Vector3d(csv.GetDouble("x_m"), csv.GetDouble("y_m"), csv.GetDouble("z_m")));
    }
    if (num_q == 4) {
      int num_empty = 0;
      for (const auto& c : q_columns) num_empty += csv.Get(c).empty() ? 1 : 0;
      if (num_empty == 0) {
        sample.enu_from_cam =
            CheckedQuaternion(csv.GetDouble("qw"), csv.GetDouble("qx"), csv.GetDouble("qy"),
                              csv.GetDouble("qz"), csv.where());
      } else if (num_empty != 4) {
        Throw("{}: qw,qx,qy,qz must be all set or all empty", csv.where());
      }
    }
    if (csv.HasColumn("frame") && !csv.Get("frame").empty()) sample.frame = csv.GetInt("frame");
    if (!track.samples.empty() && sample.timestamp_s <= track.samples.back().timestamp_s) {
      Throw("{}: timestamp {} is not after the previous one ({})", csv.where(),
            FormatDouble(sample.timestamp_s), FormatDouble(track.samples.back().timestamp_s));
    }
    track.samples.push_back(sample);
  }
  return track;
}

void WritePositionCsv(const PositionTrack& track, const std::string& path) {
  CsvWriter csv(path,
                {"timestamp_s", "lat_deg", "lon_deg", "alt_m", "qw", "qx", "qy", "qz", "frame"});
  for (const auto& s : track.samples) {
    std::vector<std::string> row = {FormatDouble(s.timestamp_s), FormatDouble(s.position.lat_deg),
                                    FormatDouble(s.position.lon_deg),
                                    FormatDouble(s.position.alt_m)};
    if (s.enu_from_cam) {
      const auto& q = *s.enu_from_cam;
      for (const double v : {q.w(), q.x(), q.y(), q.z()}) row.push_back(FormatDouble(v));
    } else {
      row.insert(row.end(), 4, "");
    }
    row.push_back(s.frame == kInvalidFrame ? "" : std::to_string(s.frame));
    csv.WriteRow(row);
  }
  csv.Close();
}

PositionTrack ReadKittiOxtsTrack(const std::string& oxts_dir) {
  PositionTrack track;
  track.source = oxts_dir;
  for (const auto& record : ReadKittiOxts(oxts_dir)) {
    PositionSample sample;
    sample.timestamp_s = record.timestamp_s;
    sample.position = record.position;
    sample.frame = record.frame;
    track.samples.push_back(sample);
  }
  return track;
}

PositionTrack ReadPositions(const std::string& path,
                            PositionFormat format,
                            const std::optional<Geodetic>& origin,
                            const std::string& nmea_date) {
  switch (format) {
    case PositionFormat::kCsv:
      return ReadPositionCsv(path, origin);
    case PositionFormat::kNmea:
      return ReadNmea(path, nmea_date);
    case PositionFormat::kKittiOxts:
      return ReadKittiOxtsTrack(path);
  }
  Throw("{}: unknown position format", path);
}

}  // namespace epiloc
