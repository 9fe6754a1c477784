#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/position_readers.h"
#include "io_internal.h"

namespace epiloc {
namespace {

// Parses exactly `count` digits of `text` at `pos`; false if any is not a digit.
bool ParseDigits(const std::string& text, size_t pos, size_t count, int64_t* value) {
  if (pos + count > text.size()) return false;
  *value = 0;
  for (size_t i = pos; i < pos + count; ++i) {
    if (!std::isdigit(static_cast<unsigned char>(text[i]))) return false;
    *value = *value * 10 + (text[i] - '0');
  }
  return true;
}

bool LooksLikeDate(const std::string& text) {
  return text.size() >= 10 && text[4] == '-' && text[7] == '-';
}

}  // namespace

std::string ResolvePath(const std::string& dir, const std::string& path) {
  if (path.empty() || dir.empty() || std::filesystem::path(path).is_absolute()) return path;
  return (std::filesystem::path(dir) / path).string();
}

bool FileExists(const std::string& path) {
  std::error_code error;
  return std::filesystem::is_regular_file(path, error);
}

std::string FileProblem(const std::string& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (std::filesystem::is_regular_file(status)) return "";
  if (!std::filesystem::exists(status)) return "not found";
  if (std::filesystem::is_directory(status)) return "is a folder, not a file";
  return "is not a regular file (a FIFO or device)";
}

Eigen::Matrix3d EnuFromEcefRotation(const Geodetic& p) {
  const double lat = p.lat_deg * M_PI / 180.0, lon = p.lon_deg * M_PI / 180.0;
  const double sl = std::sin(lat), cl = std::cos(lat), so = std::sin(lon), co = std::cos(lon);
  Eigen::Matrix3d r;
  r << -so, co, 0.0,           //
      -sl * co, -sl * so, cl,  //
      cl * co, cl * so, sl;
  return r;
}

Eigen::Quaterniond EnuToEnuRotation(const Geodetic& to, const Geodetic& from) {
  return Eigen::Quaterniond(EnuFromEcefRotation(to) * EnuFromEcefRotation(from).transpose());
}

int64_t DaysFromCivil(int64_t y, int64_t m, int64_t d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const int64_t yoe = y - era * 400;
  const int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

int DaysInMonth(int64_t year, int64_t month) {
  static const int kDays[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  if (month < 1 || month > 12) return 0;
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  return kDays[month - 1] + (month == 2 && leap ? 1 : 0);
}

int64_t ParseDateDays(const std::string& text, const std::string& where) {
  int64_t year = 0, month = 0, day = 0;
  if (!(text.size() == 10 && LooksLikeDate(text) && ParseDigits(text, 0, 4, &year) &&
        ParseDigits(text, 5, 2, &month) && ParseDigits(text, 8, 2, &day) && month >= 1 &&
        month <= 12 && day >= 1 && day <= DaysInMonth(year, month))) {
    Throw("{}: '{}' is not a date YYYY-MM-DD", where, text);
  }
  return DaysFromCivil(year, month, day);
}

double ParseTimestamp(const std::string& raw, const std::string& where) {
  const std::string text = Trim(raw);
  if (!LooksLikeDate(text)) return ParseDouble(text, where);
  // "YYYY-MM-DD HH:MM:SS[.fff...]": whole seconds in int64, the fraction added last, so a UNIX time
  // of ~1.3e9 s keeps its sub-microsecond digits up to double precision.
  int64_t hour = 0, minute = 0, second = 0;
  const bool ok = text.size() >= 19 && (text[10] == ' ' || text[10] == 'T') && text[13] == ':' &&
                  text[16] == ':' && ParseDigits(text, 11, 2, &hour) &&
                  ParseDigits(text, 14, 2, &minute) && ParseDigits(text, 17, 2, &second) &&
                  hour < 24 && minute < 60 && second <= 60;
  if (!ok) Throw("{}: '{}' is not a time YYYY-MM-DD HH:MM:SS.fff", where, text);
  const int64_t days = ParseDateDays(text.substr(0, 10), where);
  double fraction = 0.0;
  if (text.size() > 19) {
    const std::string rest = text.substr(19);
    bool digits = rest.size() >= 2 && rest[0] == '.';
    for (size_t i = 1; digits && i < rest.size(); ++i) {
      digits = std::isdigit(static_cast<unsigned char>(rest[i])) != 0;
    }
    if (!digits) Throw("{}: '{}' is not a time YYYY-MM-DD HH:MM:SS.fff", where, text);
    fraction = std::stod("0" + rest);
  }
  const int64_t whole = days * 86400 + hour * 3600 + minute * 60 + second;
  return static_cast<double>(whole) + fraction;
}

std::vector<double> ReadTimestamps(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open file", path);
  std::vector<double> times;
  std::string line;
  int64_t line_number = 0;
  int64_t first_blank = 0;
  while (ReadLine(in, line, path, line_number + 1)) {
    ++line_number;
    const std::string text = Trim(line);
    if (text.empty()) {
      if (first_blank == 0) first_blank = line_number;
      continue;
    }
    if (first_blank != 0) Throw("{}: blank line among the timestamps", Where(path, first_blank));
    const double t = ParseTimestamp(text, Where(path, line_number));
    if (!times.empty() && t < times.back()) {
      Throw("{}: timestamp {} goes backwards (previous {})", Where(path, line_number),
            FormatDouble(t), FormatDouble(times.back()));
    }
    times.push_back(t);
  }
  if (in.bad()) Throw("{}: read error", path);
  return times;
}

Eigen::Quaterniond CheckedQuaternion(
    double w, double x, double y, double z, const std::string& where) {
  Eigen::Quaterniond q(w, x, y, z);
  const double norm = q.norm();
  if (!(std::abs(norm - 1.0) <= 1e-3)) {
    Throw("{}: quaternion ({}, {}, {}, {}) is not of unit length", where, w, x, y, z);
  }
  if (std::abs(norm - 1.0) > 1e-12) q.normalize();
  return q;
}

}  // namespace epiloc
