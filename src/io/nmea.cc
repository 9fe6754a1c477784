#include <cmath>
#include <cstdlib>
#include <fstream>

#include <spdlog/spdlog.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/position_readers.h"
#include "io_internal.h"

namespace epiloc {
namespace {

constexpr double kSecondsPerDay = 86400.0;

std::vector<std::string> SplitFields(const std::string& body) {
  std::vector<std::string> fields;
  size_t begin = 0;
  while (true) {
    const size_t comma = body.find(',', begin);
    fields.push_back(Trim(body.substr(begin, comma - begin)));
    if (comma == std::string::npos) break;
    begin = comma + 1;
  }
  return fields;
}

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// The fields of a sentence (address first) with its checksum verified when present.
std::vector<std::string> ParseSentence(const std::string& text, const std::string& where) {
  if (text[0] != '$') Throw("{}: not an NMEA sentence (does not start with '$')", where);
  const size_t star = text.find('*');
  const std::string body = text.substr(1, star == std::string::npos ? std::string::npos : star - 1);
  if (star != std::string::npos) {
    const std::string given = text.substr(star + 1);
    if (given.size() != 2 || HexDigit(given[0]) < 0 || HexDigit(given[1]) < 0) {
      Throw("{}: malformed NMEA checksum '{}'", where, given);
    }
    unsigned computed = 0;
    for (const char c : body) computed ^= static_cast<unsigned char>(c);
    const unsigned expected = static_cast<unsigned>(HexDigit(given[0]) * 16 + HexDigit(given[1]));
    if (computed != expected) {
      Throw("{}: NMEA checksum mismatch: sentence says {}, computed {:02X}", where, given,
            computed);
    }
  }
  return SplitFields(body);
}

// "hhmmss[.sss]" -> seconds of the day.
double ParseTimeOfDay(const std::string& text, const std::string& where) {
  if (text.size() < 6) Throw("{}: '{}' is not an NMEA time hhmmss.ss", where, text);
  const double value = ParseDouble(text, where);
  const double hours = std::floor(value / 10000.0);
  const double minutes = std::floor((value - hours * 10000.0) / 100.0);
  const double seconds = value - hours * 10000.0 - minutes * 100.0;
  if (value < 0 || hours >= 24 || minutes >= 60 || seconds >= 61) {
    Throw("{}: '{}' is not an NMEA time hhmmss.ss", where, text);
  }
  return hours * 3600.0 + minutes * 60.0 + seconds;
}

// "ddmm.mmmm" / "dddmm.mmmm" with hemisphere "N"/"S" or "E"/"W" -> signed degrees.
double ParseAngle(const std::string& text,
                  const std::string& hemisphere,
                  const char* positive,
                  const char* negative,
                  const std::string& where) {
  const double value = ParseDouble(text, where);
  const double degrees = std::floor(value / 100.0);
  const double minutes = value - degrees * 100.0;
  if (value < 0 || minutes >= 60.0) Throw("{}: '{}' is not an NMEA angle", where, text);
  const double angle = degrees + minutes / 60.0;
  if (hemisphere == positive) return angle;
  if (hemisphere == negative) return -angle;
  Throw("{}: hemisphere '{}' is not {} or {}", where, hemisphere, positive, negative);
}

// RMC "ddmmyy" -> days since 1970-01-01 (years 80-99 are 19xx).
int64_t ParseRmcDate(const std::string& text, const std::string& where) {
  if (text.size() != 6 || text.find_first_not_of("0123456789") != std::string::npos) {
    Throw("{}: '{}' is not an NMEA date ddmmyy", where, text);
  }
  const int64_t day = std::atoi(text.substr(0, 2).c_str());
  const int64_t month = std::atoi(text.substr(2, 2).c_str());
  const int64_t yy = std::atoi(text.substr(4, 2).c_str());
  const int64_t year = yy < 80 ? 2000 + yy : 1900 + yy;
  if (day < 1 || month < 1 || month > 12 || day > DaysInMonth(year, month)) {
    Throw("{}: '{}' is not an NMEA date ddmmyy", where, text);
  }
  return DaysFromCivil(year, month, day);
}

}  // namespace

NmeaParser::NmeaParser(const std::string& path, const std::string& date) : path_(path) {
  if (!date.empty()) date_days_ = ParseDateDays(date, path + ": gnss \"date\"");
}

void NmeaParser::Feed(const std::string& line, int64_t line_number, PositionTrack* track) {
  const std::string text = Trim(line);
  if (text.empty()) return;
  const std::string where = Where(path_, line_number);
  const std::vector<std::string> f = ParseSentence(text, where);
  const std::string& address = f[0];
  const std::string type = address.size() == 5 ? address.substr(2) : "";
  const bool gga = type == "GGA", rmc = type == "RMC";
  if (!gga && !rmc) {
    ++stats_.ignored;
    return;
  }
  if (f.size() < 10) {
    Throw("{}: {} sentence has {} fields, expected at least 10", where, address, f.size());
  }
  if (rmc && !f[9].empty()) date_days_ = ParseRmcDate(f[9], where);
  if (gga && (f[6].empty() || ParseInt(f[6], where + " fix quality") == 0)) {
    ++stats_.skipped_no_fix;
    return;
  }
  if (rmc && f[2] != "A") {
    if (f[2] != "V") Throw("{}: RMC status '{}' is not A or V", where, f[2]);
    ++stats_.skipped_no_fix;
    return;
  }
  if (!date_days_) {
    Throw(
        "{}: {} before any RMC sentence gives no date; add \"date\": \"YYYY-MM-DD\" to the "
        "position entry in drive.json",
        where, address);
  }
  const int lat_index = gga ? 2 : 3;
  PositionSample sample;
  sample.position.lat_deg = ParseAngle(f[lat_index], f[lat_index + 1], "N", "S", where);
  sample.position.lon_deg = ParseAngle(f[lat_index + 2], f[lat_index + 3], "E", "W", where);
  if (gga && !f[9].empty()) last_altitude_m_ = ParseDouble(f[9], where + " altitude");
  sample.position.alt_m = last_altitude_m_;
  CheckGeodetic(sample.position, where);
  sample.timestamp_s =
      static_cast<double>(*date_days_) * kSecondsPerDay + ParseTimeOfDay(f[1], where);
  if (!track->samples.empty()) {
    // A GGA (or an RMC without date) just after midnight still has the previous day's date, one
    // just before midnight may follow an RMC of the new day.
    const double previous = track->samples.back().timestamp_s;
    const bool own_date = rmc && !f[9].empty();
    if (!own_date && sample.timestamp_s < previous - kSecondsPerDay / 2) {
      *date_days_ += 1;
      sample.timestamp_s += kSecondsPerDay;
    } else if (!own_date && sample.timestamp_s > previous + kSecondsPerDay / 2) {
      *date_days_ -= 1;
      sample.timestamp_s -= kSecondsPerDay;
    }
    PositionSample& last = track->samples.back();
    if (std::abs(sample.timestamp_s - previous) < 1e-6) {
      // Same epoch: one sample, the GGA position (with its altitude) preferred.
      if (gga || !last_from_gga_) last = sample;
      last_from_gga_ = last_from_gga_ || gga;
      return;
    }
    if (sample.timestamp_s < previous) {
      Throw("{}: time {} goes backwards (previous {})", where, FormatDouble(sample.timestamp_s),
            FormatDouble(previous));
    }
  }
  track->samples.push_back(sample);
  last_from_gga_ = gga;
}

PositionTrack ReadNmea(const std::string& path, const std::string& date, NmeaStats* stats_out) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open file", path);
  PositionTrack track;
  track.source = path;
  NmeaParser parser(path, date);
  std::string line;
  int64_t line_number = 0;
  while (ReadLine(in, line, path, line_number + 1)) parser.Feed(line, ++line_number, &track);
  if (in.bad()) Throw("{}: read error", path);
  NmeaStats stats = parser.stats();
  stats.positions = static_cast<int64_t>(track.samples.size());
  if (stats.skipped_no_fix > 0) {
    spdlog::info("{}: {} positions, {} sentences without a fix skipped", path, stats.positions,
                 stats.skipped_no_fix);
  }
  if (stats_out) *stats_out = stats;
  return track;
}

}  // namespace epiloc
