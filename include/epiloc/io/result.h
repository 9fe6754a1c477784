// The localizer's per-frame result file ("result CSV"), read by `epiloc evaluate` and
// `epiloc export` and written by the localizer.
//
// Format: CSV as in core/csv.h (header row, '#' comment lines, quoted fields), one row per input
// frame and method, so one file can carry several methods side by side. Required columns, in any
// order:
//   frame        the drive's frame number (integer >= 0; empty = none, then association is by time)
//   timestamp_s  frame time in seconds, same clock as the ground truth (UNIX time for real data)
//   lat_deg, lon_deg, alt_m   estimated camera centre, WGS-84 degrees / metres; required for
//                status ok, may be empty otherwise
//   s_m          the localizer's along-route distance in its database's route, metres (may be
//                empty; informative: `evaluate` projects lat/lon onto its evaluation route so that
//                every method is measured the same way)
//   db_frame     the matched database frame (image id; empty = none)
//   method       any name (letters, digits, _ - . +; another tool's output keeps its own); the
//                KnownMethods() (e.g. gps, dtw_fixed, pnp) are listed first in their order
//   status       one of ok | lost | off_route | rejected | skipped (see ResultStatus)
// Optional columns with a meaning: qw,qx,qy,qz (all four or none; per row all set or all empty):
// enu_from_cam, rotation from the camera frame (x right, y down, z forward) to the local ENU frame
// at the estimate, as in the position CSV. Any other column (heading_deg, cross_track_m, quality,
// ...) is kept as text in `extra` and written back unchanged.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "epiloc/core/csv.h"
#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"

namespace epiloc {

// The names of the estimates a result can carry, in the order tables list them: "gps" (the
// drive's own GNSS), "nearest" (nearest database frame), "dtw_fixed", "fit_fixed", "dtw_free",
// "fit_free" (Kyutoku et al. DTW / V-fit with fixed or free ends), "online", "pnp" (6-DoF
// refinement against the survey's triangulated points), "anchor" (rendered LiDAR, Kurobe et al.),
// "vo", "paper", "sim3", "piecewise" (georeferenced VO), "colmap" (COLMAP image registration,
// tools/compare_colmap.sh). The one place they are listed.
const std::vector<std::string>& KnownMethods();
bool IsKnownMethod(const std::string& name);
// Throws Error "<where>: method name ..." unless `name` is 1-64 letters, digits, _ - . + (or
// UTF-8 letters): any tool's method is accepted, as long as it is safe in file names and reports.
void CheckMethodName(const std::string& name, const std::string& where);
// Position of a method in KnownMethods() (for sorting); KnownMethods().size() if unknown.
size_t MethodRank(const std::string& name);

// Whether the frame was localized. Only kOk rows enter the error statistics; the others are
// counted per method.
enum class ResultStatus {
  kOk,        // "ok": localized, the position is the estimate
  kLost,      // "lost": the method could not localize the frame (no match, tracking lost)
  kOffRoute,  // "off_route": the vehicle was judged to be off the surveyed route
  kRejected,  // "rejected": an estimate was made but failed the method's quality check
  kSkipped,   // "skipped": the method did not process the frame (frame step, initialization)
};
// "ok", "lost", "off_route", "rejected", "skipped".
const std::vector<std::string>& StatusNames();
std::string StatusName(ResultStatus status);
// Throws Error "<where>: unknown status 'x' (known: ok, lost, ...)".
ResultStatus ParseStatus(const std::string& name, const std::string& where);

struct ResultRow {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  Geodetic position;  // meaningful when has_position
  bool has_position = false;
  double s_m = 0.0;  // meaningful when has_s
  bool has_s = false;
  image_t db_frame = kInvalidImage;
  std::string method;
  ResultStatus status = ResultStatus::kOk;
  std::optional<Eigen::Quaterniond> enu_from_cam;
  std::vector<std::string> extra;  // values of ResultTable::extra_columns, in that order
  int64_t line = 0;                // line in the file it was read from (0 = not read from a file)
};

struct ResultTable {
  std::string path;                        // file read, for messages
  std::vector<std::string> extra_columns;  // optional columns kept as text
  std::vector<ResultRow> rows;             // file order

  // Methods present, in KnownMethods() order.
  std::vector<std::string> Methods() const;
};

// Reads a result CSV. Throws Error naming the file and line for a missing required column (line
// of the header), a malformed method name, an unknown status (listing the known ones), a field that does not
// parse (NaN and inf included), an ok row without position, a frame repeated within a method,
// lat/lon out of range, or a file without rows.
ResultTable ReadResultCsv(const std::string& path);

// Writes result rows as they are made (a streaming localizer): the header first (required
// columns, qw..qz when `with_orientation`, then `extra_columns`), then each row; `path` "-" is
// standard output. Rows with an orientation need with_orientation; each row needs one value per
// extra column.
class ResultCsvWriter {
 public:
  ResultCsvWriter(const std::string& path,
                  const std::vector<std::string>& extra_columns,
                  bool with_orientation);
  void Write(const ResultRow& row);
  // Hands the rows written so far on (CsvWriter::Flush).
  void Flush();
  void Close();

 private:
  std::string path_;
  size_t num_extra_;
  bool with_orientation_;
  CsvWriter writer_;
};

// Writes the required columns, qw..qz when any row has an orientation, then the extra columns;
// doubles with full precision so that ReadResultCsv gives the same rows back.
void WriteResultCsv(const ResultTable& table, const std::string& path);

}  // namespace epiloc
