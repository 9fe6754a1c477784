// Helpers shared by the io sources; not part of the public API.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "epiloc/core/csv.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/position_readers.h"

namespace epiloc {

// `path` if absolute or `dir` empty, else dir/path.
std::string ResolvePath(const std::string& dir, const std::string& path);
bool FileExists(const std::string& path);
// "" for a regular file, else what is wrong: "not found", "is a folder, not a file", "is not a
// regular file (a FIFO or device)".
std::string FileProblem(const std::string& path);

// Rotation from the ECEF axes to the local ENU axes at `position`.
Eigen::Matrix3d EnuFromEcefRotation(const Geodetic& position);
// Rotation taking vectors in the ENU axes at `from` to the ENU axes at `to`.
Eigen::Quaterniond EnuToEnuRotation(const Geodetic& to, const Geodetic& from);

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
int64_t DaysFromCivil(int64_t year, int64_t month, int64_t day);
// Days of a month of the Gregorian calendar (February 29 in leap years); 0 for a bad month.
int DaysInMonth(int64_t year, int64_t month);
// Parses "YYYY-MM-DD" into days since 1970-01-01; throws Error "<where>: ..." when malformed.
int64_t ParseDateDays(const std::string& text, const std::string& where);

// Checks a quaternion read from a file: normalises it if within 1e-3 of unit length (values
// within 1e-12 are kept as they are, so written quaternions read back bit for bit), else throws.
Eigen::Quaterniond CheckedQuaternion(
    double w, double x, double y, double z, const std::string& where);

// LiDAR CSV: scan,timestamp_s,path,format,lat_deg,lon_deg,alt_m,qw,qx,qy,qz. Scan files are
// checked to exist relative to `dir`.
std::vector<LidarScan> ReadLidarCsv(const std::string& path, const std::string& dir);
void WriteLidarCsv(const std::vector<LidarScan>& scans, const std::string& path);

// The rows of a frames CSV one at a time, with the checks of ReadFramesCsv (unique frame numbers,
// times never decreasing, image files exist); `appended` reads a file still being written
// (CsvReader::NextAppended).
class FramesCsvRows {
 public:
  FramesCsvRows(const std::string& path, const std::string& dir, bool video);
  bool Next(FrameRecord* record, bool appended = false);

 private:
  CsvReader csv_;
  std::string dir_;
  bool video_;
  std::unordered_map<frame_t, int64_t> line_of_frame_;
  std::optional<double> last_timestamp_s_;
};

// The rows of a position CSV one at a time, with the checks of ReadPositionCsv.
class PositionCsvRows {
 public:
  PositionCsvRows(const std::string& path, const std::optional<Geodetic>& origin);
  bool Next(PositionSample* sample, bool appended = false);

 private:
  CsvReader csv_;
  bool geodetic_ = false;
  std::optional<EnuFrame> enu_;
  int num_q_ = 0;
  bool has_status_ = false;  // a result CSV: rows whose status is not ok are skipped
  std::optional<double> last_timestamp_s_;
};

// NMEA 0183 sentences one line at a time (ReadNmea's rules), appended to a track.
class NmeaParser {
 public:
  NmeaParser(const std::string& path, const std::string& date);
  void Feed(const std::string& line, int64_t line_number, PositionTrack* track);
  const NmeaStats& stats() const { return stats_; }

 private:
  std::string path_;
  NmeaStats stats_;
  std::optional<int64_t> date_days_;
  double last_altitude_m_ = 0.0;
  bool last_from_gga_ = false;
};

// Frames from a CSV of frame,timestamp_s,image (image optional and empty when `video` is true).
// Image files are checked to exist relative to `dir`.
std::vector<FrameRecord> ReadFramesCsv(const std::string& path, const std::string& dir, bool video);
// Frames from the PNG/JPEG files of `folder` (`folder_as_given` is the path written into the
// records); times from `timestamps_path` when set, else start_s + (frame - first frame) / fps.
std::vector<FrameRecord> ReadFramesFolder(const std::string& folder,
                                          const std::string& folder_as_given,
                                          const std::string& timestamps_path,
                                          double fps,
                                          double start_s);
// Frames of a video: times from `timestamps_path`, or fps, or (both unset) the video's own frame
// times plus start_s.
std::vector<FrameRecord> ReadFramesVideo(const std::string& video_path,
                                         const std::string& timestamps_path,
                                         double fps,
                                         double start_s);
// Throws Error "<where>: frame N appears twice" / "frame times go backwards".
void CheckFrameOrder(const std::vector<FrameRecord>& frames, const std::string& where);

}  // namespace epiloc
