#include "epiloc/io/nmea_writer.h"

#include <cmath>
#include <cstdint>
#include <exception>
#include <iostream>

#include <fmt/format.h>

#include "epiloc/core/error.h"
#include "io_internal.h"

namespace epiloc {
namespace {

constexpr double kSecondsPerDay = 86400.0;
constexpr double kKnotsPerMps = 3600.0 / 1852.0;

// "hhmmss.ss" of the UTC time of day, rounded to the hundredth (carrying into the next day is
// avoided by flooring the day first).
std::string TimeOfDay(double timestamp_s) {
  const double day_start = std::floor(timestamp_s / kSecondsPerDay) * kSecondsPerDay;
  int64_t centis = std::llround((timestamp_s - day_start) * 100.0);
  centis = std::min<int64_t>(centis, 8639999);
  const int64_t seconds = centis / 100;
  return fmt::format("{:02d}{:02d}{:02d}.{:02d}", seconds / 3600, (seconds / 60) % 60, seconds % 60,
                     centis % 100);
}

// "ddmmyy" of the UTC date (H. Hinnant's civil_from_days).
std::string Date(double timestamp_s) {
  int64_t z = static_cast<int64_t>(std::floor(timestamp_s / kSecondsPerDay)) + 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const int64_t doe = z - era * 146097;
  const int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const int64_t mp = (5 * doy + 2) / 153;
  const int64_t d = doy - (153 * mp + 2) / 5 + 1;
  const int64_t m = mp < 10 ? mp + 3 : mp - 9;
  const int64_t y = yoe + era * 400 + (m <= 2 ? 1 : 0);
  return fmt::format("{:02d}{:02d}{:02d}", d, m, ((y % 100) + 100) % 100);
}

// "ddmm.mmmmmmm,N" / "dddmm.mmmmmmm,E".
std::string Angle(double degrees, int degree_digits, char positive, char negative) {
  const char hemisphere = degrees < 0 ? negative : positive;
  const double a = std::abs(degrees);
  int whole = static_cast<int>(a);
  double minutes = (a - whole) * 60.0;
  if (std::llround(minutes * 1e7) >= 600000000LL) {  // rounds up to 60'
    ++whole;
    minutes = 0.0;
  }
  return fmt::format("{:0{}d}{:010.7f},{}", whole, degree_digits, minutes, hemisphere);
}

std::string Sentence(const std::string& body) { return "$" + body + "*" + NmeaChecksum(body); }

}  // namespace

std::string NmeaChecksum(const std::string& body) {
  uint8_t sum = 0;
  for (const char c : body) sum ^= static_cast<uint8_t>(c);
  return fmt::format("{:02X}", sum);
}

std::string FormatGga(double timestamp_s, const Geodetic& position, const std::string& talker) {
  return Sentence(fmt::format("{}GGA,{},{},{},6,00,,{:.3f},M,0.0,M,,", talker,
                              TimeOfDay(timestamp_s), Angle(position.lat_deg, 2, 'N', 'S'),
                              Angle(position.lon_deg, 3, 'E', 'W'), position.alt_m));
}

std::string FormatRmc(double timestamp_s,
                      const Geodetic& position,
                      std::optional<double> speed_mps,
                      std::optional<double> course_deg,
                      const std::string& talker) {
  return Sentence(
      fmt::format("{}RMC,{},A,{},{},{},{},{},,,E", talker, TimeOfDay(timestamp_s),
                  Angle(position.lat_deg, 2, 'N', 'S'), Angle(position.lon_deg, 3, 'E', 'W'),
                  speed_mps ? fmt::format("{:.3f}", *speed_mps * kKnotsPerMps) : "",
                  course_deg ? fmt::format("{:.2f}", *course_deg) : "", Date(timestamp_s)));
}

NmeaWriter::NmeaWriter(const std::string& path)
    : path_(path == "-" ? "standard output" : path),
      uncaught_exceptions_(std::uncaught_exceptions()) {
  if (path == "-") {
    out_ = &std::cout;
  } else {
    atomic_ = std::make_unique<AtomicFile>(path);
    file_.open(atomic_->temp_path());
    if (!file_) Throw("{}: cannot open for writing", path);
    out_ = &file_;
  }
}

NmeaWriter::~NmeaWriter() {
  if (atomic_ && std::uncaught_exceptions() > uncaught_exceptions_) {
    if (file_.is_open()) file_.close();
    atomic_->Discard();  // a failed run leaves no partial file
    return;
  }
  try {
    Close();
  } catch (const Error&) {
  }
}

void NmeaWriter::Write(double timestamp_s, const Geodetic& position) {
  EPILOC_CHECK(out_, "{}: already closed", path_);
  std::optional<double> speed_mps, course_deg;
  if (last_position_ && last_time_s_ && timestamp_s > *last_time_s_) {
    const Eigen::Vector3d step = EnuFrame(*last_position_).ToEnu(position);
    speed_mps = step.head<2>().norm() / (timestamp_s - *last_time_s_);
    if (step.head<2>().norm() > 1e-3) {
      course_deg = std::fmod(std::atan2(step.x(), step.y()) * 180.0 / M_PI + 360.0, 360.0);
    }
  }
  // RMC first: it carries the date, which a reader needs before the epoch's GGA.
  *out_ << FormatRmc(timestamp_s, position, speed_mps, course_deg) << "\r\n"
        << FormatGga(timestamp_s, position) << "\r\n";
  out_->flush();
  if (!*out_) Throw("{}: write failed", path_);
  last_time_s_ = timestamp_s;
  last_position_ = position;
}

void NmeaWriter::Close() {
  if (!out_) return;
  out_->flush();
  bool ok = static_cast<bool>(*out_);
  if (file_.is_open()) {
    file_.close();
    ok = ok && !file_.fail();
  }
  out_ = nullptr;
  if (!ok) {
    if (atomic_) atomic_->Discard();
    Throw("{}: write failed", path_);
  }
  if (atomic_) atomic_->Commit();
}

}  // namespace epiloc
