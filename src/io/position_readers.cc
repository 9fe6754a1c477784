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

PositionCsvRows::PositionCsvRows(const std::string& path, const std::optional<Geodetic>& origin)
    : csv_(path) {
  csv_.RequireColumns({"timestamp_s"});
  geodetic_ = csv_.HasColumn("lat_deg") || csv_.HasColumn("lon_deg");
  if (geodetic_) {
    csv_.RequireColumns({"lat_deg", "lon_deg", "alt_m"});
  } else if (csv_.HasColumn("x_m") || csv_.HasColumn("y_m") || csv_.HasColumn("z_m")) {
    csv_.RequireColumns({"x_m", "y_m", "z_m"});
    if (!origin) {
      Throw("{}: local x_m,y_m,z_m positions need an \"origin\" in drive.json", path);
    }
    enu_.emplace(*origin);
  } else {
    Throw("{}: missing columns lat_deg,lon_deg,alt_m or x_m,y_m,z_m", path);
  }
  has_status_ = csv_.HasColumn("status");
  for (const char* c : {"qw", "qx", "qy", "qz"}) num_q_ += csv_.HasColumn(c) ? 1 : 0;
  if (num_q_ != 0 && num_q_ != 4) Throw("{}: needs all of the columns qw,qx,qy,qz or none", path);
}

bool PositionCsvRows::Next(PositionSample* out, bool appended) {
  // A result CSV used as positions: only rows the method localized are positions; a lost or
  // rejected row's coordinates are a prediction at best.
  do {
    if (!(appended ? csv_.NextAppended() : csv_.Next())) return false;
  } while (has_status_ && Trim(csv_.Get("status")) != "ok");
  PositionSample sample;
  sample.timestamp_s = csv_.GetDouble("timestamp_s");
  if (geodetic_) {
    sample.position = {csv_.GetDouble("lat_deg"), csv_.GetDouble("lon_deg"),
                       csv_.GetDouble("alt_m")};
    CheckGeodetic(sample.position, csv_.where());
  } else {
    sample.position = enu_->ToGeodetic(
        Eigen::Vector3d(csv_.GetDouble("x_m"), csv_.GetDouble("y_m"), csv_.GetDouble("z_m")));
  }
  if (num_q_ == 4) {
    int num_empty = 0;
    for (const char* c : {"qw", "qx", "qy", "qz"}) num_empty += csv_.Get(c).empty() ? 1 : 0;
    if (num_empty == 0) {
      sample.enu_from_cam =
          CheckedQuaternion(csv_.GetDouble("qw"), csv_.GetDouble("qx"), csv_.GetDouble("qy"),
                            csv_.GetDouble("qz"), csv_.where());
    } else if (num_empty != 4) {
      Throw("{}: qw,qx,qy,qz must be all set or all empty", csv_.where());
    }
  }
  if (csv_.HasColumn("frame") && !csv_.Get("frame").empty()) sample.frame = csv_.GetInt("frame");
  if (last_timestamp_s_ && sample.timestamp_s <= *last_timestamp_s_) {
    Throw("{}: timestamp {} is not after the previous one ({})", csv_.where(),
          FormatDouble(sample.timestamp_s), FormatDouble(*last_timestamp_s_));
  }
  last_timestamp_s_ = sample.timestamp_s;
  *out = std::move(sample);
  return true;
}

PositionTrack ReadPositionCsv(const std::string& path, const std::optional<Geodetic>& origin) {
  PositionCsvRows rows(path, origin);
  PositionTrack track;
  track.source = path;
  PositionSample sample;
  while (rows.Next(&sample)) track.samples.push_back(sample);
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
  const std::vector<OxtsRecord> records = ReadKittiOxts(oxts_dir);
  // The same positions ImportKitti uses by default: consistent with the unit's velocity.
  const FusedOxts fused = FuseOxtsPositions(records);
  for (size_t i = 0; i < records.size(); ++i) {
    PositionSample sample;
    sample.timestamp_s = records[i].timestamp_s;
    sample.position = fused.positions[i];
    sample.frame = records[i].frame;
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
