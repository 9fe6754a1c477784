#include "epiloc/io/result.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

const std::vector<std::string> kRequiredColumns = {
    "frame", "timestamp_s", "lat_deg", "lon_deg", "alt_m", "s_m", "db_frame", "method", "status"};
const std::vector<std::string> kQuaternionColumns = {"qw", "qx", "qy", "qz"};

bool IsRequiredOrQuaternion(const std::string& column) {
  const auto has = [&](const std::vector<std::string>& list) {
    return std::find(list.begin(), list.end(), column) != list.end();
  };
  return has(kRequiredColumns) || has(kQuaternionColumns);
}

}  // namespace

const std::vector<std::string>& KnownMethods() {
  static const std::vector<std::string> methods = {
      "gps", "nearest", "dtw_fixed", "fit_fixed", "dtw_free", "fit_free",  "online",
      "pnp", "anchor",  "vo",        "paper",     "sim3",     "piecewise", "colmap"};
  return methods;
}

bool IsKnownMethod(const std::string& name) { return MethodRank(name) < KnownMethods().size(); }

void CheckMethodName(const std::string& name, const std::string& where) {
  if (name.empty()) Throw("{}: empty method name", where);
  if (name.size() > 64) Throw("{}: method name longer than 64 characters", where);
  for (const char c : name) {
    const auto u = static_cast<unsigned char>(c);
    if (!(std::isalnum(u) || c == '_' || c == '-' || c == '.' || c == '+' || u >= 0x80)) {
      Throw("{}: method name '{}' may hold only letters, digits and _ - . +", where,
            Printable(name));
    }
  }
}

size_t MethodRank(const std::string& name) {
  const auto& methods = KnownMethods();
  return static_cast<size_t>(std::find(methods.begin(), methods.end(), name) - methods.begin());
}

const std::vector<std::string>& StatusNames() {
  static const std::vector<std::string> names = {"ok", "lost", "off_route", "rejected", "skipped"};
  return names;
}

std::string StatusName(ResultStatus status) { return StatusNames()[static_cast<size_t>(status)]; }

ResultStatus ParseStatus(const std::string& name, const std::string& where) {
  const auto& names = StatusNames();
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) {
    Throw("{}: unknown status '{}' (known: {})", where, name, fmt::join(names, ", "));
  }
  return static_cast<ResultStatus>(it - names.begin());
}

std::vector<std::string> ResultTable::Methods() const {
  std::vector<std::string> methods;
  for (const auto& row : rows) {
    if (std::find(methods.begin(), methods.end(), row.method) == methods.end()) {
      methods.push_back(row.method);
    }
  }
  std::stable_sort(methods.begin(), methods.end(), [](const std::string& a, const std::string& b) {
    return MethodRank(a) < MethodRank(b);
  });
  return methods;
}

ResultTable ReadResultCsv(const std::string& path) {
  CsvReader csv(path);
  const int64_t header_line = csv.line();
  for (const auto& column : kRequiredColumns) {
    if (!csv.HasColumn(column)) {
      Throw("{}: missing column '{}' (a result needs {})", Where(path, header_line), column,
            fmt::join(kRequiredColumns, ","));
    }
  }
  int num_q = 0;
  for (const auto& c : kQuaternionColumns) num_q += csv.HasColumn(c) ? 1 : 0;
  if (num_q != 0 && num_q != 4) {
    Throw("{}: needs all of the columns qw,qx,qy,qz or none", Where(path, header_line));
  }

  ResultTable table;
  table.path = path;
  for (const auto& column : csv.header()) {
    if (!IsRequiredOrQuaternion(column)) table.extra_columns.push_back(column);
  }
  std::map<std::pair<std::string, frame_t>, int64_t> seen;  // (method, frame) -> line
  while (csv.Next()) {
    const std::string where = csv.where();
    ResultRow row;
    row.line = csv.line();
    row.method = csv.Get("method");
    CheckMethodName(row.method, where);
    row.status = ParseStatus(csv.Get("status"), where);
    row.timestamp_s = csv.GetDouble("timestamp_s");
    if (!csv.Get("frame").empty()) {
      row.frame = csv.GetInt("frame");
      if (row.frame < 0) Throw("{}: negative frame number {}", where, row.frame);
      const auto [it, inserted] = seen.emplace(std::make_pair(row.method, row.frame), row.line);
      if (!inserted) {
        Throw("{}: method '{}' has frame {} twice (first at line {})", where, row.method, row.frame,
              it->second);
      }
    }
    const bool has_lat = !csv.Get("lat_deg").empty();
    const bool has_lon = !csv.Get("lon_deg").empty();
    const bool has_alt = !csv.Get("alt_m").empty();
    if (has_lat || has_lon || has_alt || row.status == ResultStatus::kOk) {
      if (!(has_lat && has_lon && has_alt)) {
        Throw("{}: {}lat_deg, lon_deg and alt_m must all be set{}", where,
              row.status == ResultStatus::kOk ? "status ok: " : "",
              row.status == ResultStatus::kOk ? "" : " or all empty");
      }
      row.position = {csv.GetDouble("lat_deg"), csv.GetDouble("lon_deg"), csv.GetDouble("alt_m")};
      CheckGeodetic(row.position, where);
      row.has_position = true;
    }
    if (const auto s = csv.GetOptionalDouble("s_m")) {
      row.s_m = *s;
      row.has_s = true;
    }
    if (!csv.Get("db_frame").empty()) row.db_frame = csv.GetInt("db_frame");
    if (num_q == 4) {
      int num_empty = 0;
      for (const auto& c : kQuaternionColumns) num_empty += csv.Get(c).empty() ? 1 : 0;
      if (num_empty == 0) {
        Eigen::Quaterniond q(csv.GetDouble("qw"), csv.GetDouble("qx"), csv.GetDouble("qy"),
                             csv.GetDouble("qz"));
        if (std::abs(q.norm() - 1.0) > 1e-3) {
          Throw("{}: quaternion qw,qx,qy,qz has norm {}, expected 1", where, q.norm());
        }
        row.enu_from_cam = q.normalized();
      } else if (num_empty != 4) {
        Throw("{}: qw,qx,qy,qz must be all set or all empty", where);
      }
    }
    for (const auto& column : table.extra_columns) row.extra.push_back(csv.Get(column));
    table.rows.push_back(std::move(row));
  }
  if (table.rows.empty()) Throw("{}: no rows (an empty result)", Where(path, header_line + 1));
  return table;
}

namespace {

std::vector<std::string> ResultHeader(const std::vector<std::string>& extra_columns,
                                      bool with_orientation) {
  std::vector<std::string> header = kRequiredColumns;
  if (with_orientation) {
    header.insert(header.end(), kQuaternionColumns.begin(), kQuaternionColumns.end());
  }
  header.insert(header.end(), extra_columns.begin(), extra_columns.end());
  return header;
}

}  // namespace

ResultCsvWriter::ResultCsvWriter(const std::string& path,
                                 const std::vector<std::string>& extra_columns,
                                 bool with_orientation)
    : path_(path),
      num_extra_(extra_columns.size()),
      with_orientation_(with_orientation),
      writer_(path, ResultHeader(extra_columns, with_orientation)) {}

void ResultCsvWriter::Write(const ResultRow& row) {
  EPILOC_CHECK(row.extra.size() == num_extra_,
               "{}: row of frame {} has {} extra values for {} extra columns", path_, row.frame,
               row.extra.size(), num_extra_);
  EPILOC_CHECK(with_orientation_ || !row.enu_from_cam,
               "{}: row of frame {} has an orientation but the file has no qw..qz columns", path_,
               row.frame);
  std::vector<std::string> fields = {
      row.frame == kInvalidFrame ? "" : std::to_string(row.frame),
      FormatDouble(row.timestamp_s),
      row.has_position ? FormatDouble(row.position.lat_deg) : "",
      row.has_position ? FormatDouble(row.position.lon_deg) : "",
      row.has_position ? FormatDouble(row.position.alt_m) : "",
      row.has_s ? FormatDouble(row.s_m) : "",
      row.db_frame == kInvalidImage ? "" : std::to_string(row.db_frame),
      row.method,
      StatusName(row.status)};
  if (with_orientation_) {
    if (row.enu_from_cam) {
      const auto& q = *row.enu_from_cam;
      for (const double v : {q.w(), q.x(), q.y(), q.z()}) fields.push_back(FormatDouble(v));
    } else {
      fields.insert(fields.end(), 4, "");
    }
  }
  fields.insert(fields.end(), row.extra.begin(), row.extra.end());
  writer_.WriteRow(fields);
}

void ResultCsvWriter::Flush() { writer_.Flush(); }

void ResultCsvWriter::Close() { writer_.Close(); }

void WriteResultCsv(const ResultTable& table, const std::string& path) {
  const bool any_q = std::any_of(table.rows.begin(), table.rows.end(),
                                 [](const ResultRow& r) { return r.enu_from_cam.has_value(); });
  ResultCsvWriter writer(path, table.extra_columns, any_q);
  for (const auto& row : table.rows) writer.Write(row);
  writer.Close();
}

}  // namespace epiloc
