// Readers of timestamps and position files: CSV (lat/lon/alt or local x/y/z), NMEA GGA/RMC and
// KITTI OXTS folders. Every reader returns samples sorted by strictly increasing time and throws
// Error naming the file and line of the first bad entry (malformed line, time going backwards or
// repeating, latitude/longitude out of range).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {

// A timestamp in seconds: either a plain number ("1317042272.35195") or KITTI's
// "YYYY-MM-DD HH:MM:SS.fffffffff", read as UTC and converted to UNIX seconds (whole seconds are
// computed in int64, so the result keeps ~1e-6 s precision). `where` prefixes error messages.
double ParseTimestamp(const std::string& text, const std::string& where);

// One timestamp per line (see ParseTimestamp); line i (0-based) is entry i. Trailing blank lines
// are ignored, blank lines in between are an error. Throws Error "<path>:<line>: ..." on a bad
// line or a timestamp smaller than the one before (equal ones are accepted).
std::vector<double> ReadTimestamps(const std::string& path);

enum class PositionFormat {
  kCsv,        // timestamp_s + lat_deg,lon_deg,alt_m or x_m,y_m,z_m; optional qw..qz, frame
  kNmea,       // $--GGA / $--RMC sentences
  kKittiOxts,  // KITTI OXTS folder: data/NNNNNNNNNN.txt + timestamps.txt
};
// "csv", "nmea", "kitti_oxts"; an unknown name throws Error "<where>: unknown position format".
PositionFormat ParsePositionFormat(const std::string& name, const std::string& where);
std::string PositionFormatName(PositionFormat format);

// Position CSV. Columns: timestamp_s (seconds), then either lat_deg,lon_deg,alt_m (WGS-84) or
// x_m,y_m,z_m (metres east/north/up about `origin`, which is then required); optionally
// qw,qx,qy,qz (all four, or all empty: enu_from_cam, rotation from the camera frame x right,
// y down, z forward to the local ENU frame at the sample; normalised if within 1e-3 of unit
// length, else an error) and frame (integer, empty = none). A file with a status column (a result
// CSV) gives only its rows whose status is ok.
PositionTrack ReadPositionCsv(const std::string& path, const std::optional<Geodetic>& origin);
// Writes the canonical position CSV: timestamp_s,lat_deg,lon_deg,alt_m,qw,qx,qy,qz,frame with
// full double precision (empty fields for a missing orientation or frame).
void WritePositionCsv(const PositionTrack& track, const std::string& path);

// Counts of an NMEA file's sentences.
struct NmeaStats {
  int64_t positions = 0;       // samples produced (GGA and RMC of one epoch make one sample)
  int64_t skipped_no_fix = 0;  // GGA with fix quality 0 and RMC with status V
  int64_t ignored = 0;         // other sentence types
};

// NMEA 0183 log, one sentence per line. Uses $--GGA (position, altitude) and $--RMC (position,
// date) of any talker (GP, GN, ...); other sentences are ignored. A checksum, when present, must
// match (else Error "<path>:<line>: NMEA checksum ..."). Time = UTC time of day of the sentence on
// the date of the latest RMC; a GGA before any RMC needs `date` ("YYYY-MM-DD", else Error). A time
// of day that falls more than 12 h behind the previous one is taken to have crossed midnight.
// Sentences of one epoch (same time) are merged into one sample, position from GGA when there is
// one; altitude (metres, GGA field 9 as given) from GGA, RMC-only epochs take the last GGA
// altitude or 0. GGA fix quality 0 and RMC status V are skipped and counted.
PositionTrack ReadNmea(const std::string& path,
                       const std::string& date = "",
                       NmeaStats* stats = nullptr);

// KITTI OXTS folder `oxts_dir` (data/NNNNNNNNNN.txt, 30 values each, and timestamps.txt whose line
// n is the time of file n): the OXTS unit's positions, fused with its velocity as ImportKitti does
// by default (FuseOxtsPositions in kitti.h; as recorded when the records carry no accuracies),
// with `frame` = file number and no orientation (the camera's mounting is not part of the folder;
// ImportKitti derives camera positions and orientations from the calibration).
PositionTrack ReadKittiOxtsTrack(const std::string& oxts_dir);

// Reads `path` in `format`. `origin` is used by CSV local x/y/z positions, `nmea_date` by NMEA.
PositionTrack ReadPositions(const std::string& path,
                            PositionFormat format,
                            const std::optional<Geodetic>& origin = std::nullopt,
                            const std::string& nmea_date = "");

}  // namespace epiloc
