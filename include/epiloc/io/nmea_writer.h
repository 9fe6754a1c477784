// NMEA 0183 output of a position solution that does not come from GNSS (the localizer's), for
// navigation software and gpsd: per epoch one GGA and one RMC sentence with valid checksums.
//   GGA: fix quality 6 ("estimated", dead reckoning: not a GNSS fix), no satellite count or HDOP;
//        the altitude field carries the WGS-84 ellipsoidal height and the geoid separation is 0
//        (no geoid model is available offline), so altitude + separation is the ellipsoidal
//        height, as readers (gpsd, epiloc's ReadNmea) add them.
//   RMC: status A, mode indicator E (estimated), speed (knots) and course (degrees true) from the
//        previous epoch when there is one, date from the timestamp.
// Latitude and longitude are written with 7 decimals of minutes (~0.2 mm).
#pragma once

#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "epiloc/core/output_file.h"
#include "epiloc/geo/geodetic.h"

namespace epiloc {

// The two hex digits of the XOR of the characters between '$' and '*'.
std::string NmeaChecksum(const std::string& body);

// One sentence with '$' and "*hh" (no line end). `timestamp_s`: UNIX time (UTC).
std::string FormatGga(double timestamp_s,
                      const Geodetic& position,
                      const std::string& talker = "GP");
std::string FormatRmc(double timestamp_s,
                      const Geodetic& position,
                      std::optional<double> speed_mps,
                      std::optional<double> course_deg,
                      const std::string& talker = "GP");

// Writes RMC + GGA per epoch (RMC first: it dates the epoch) to a file ("-": standard output,
// flushed per epoch). A file is written under a temporary name and renamed into place by Close()
// or the destructor; destroyed by an exception, the writer leaves no file.
class NmeaWriter {
 public:
  explicit NmeaWriter(const std::string& path);
  NmeaWriter(const NmeaWriter&) = delete;
  NmeaWriter& operator=(const NmeaWriter&) = delete;
  ~NmeaWriter();

  // Epochs in increasing time; speed and course come from the previous epoch's position.
  void Write(double timestamp_s, const Geodetic& position);
  void Close();

 private:
  std::string path_;
  std::unique_ptr<AtomicFile> atomic_;  // a file is renamed into place by Close()
  int uncaught_exceptions_;             // at construction: tells unwinding from a normal end
  std::ofstream file_;
  std::ostream* out_ = nullptr;
  std::optional<double> last_time_s_;
  std::optional<Geodetic> last_position_;
};

}  // namespace epiloc
