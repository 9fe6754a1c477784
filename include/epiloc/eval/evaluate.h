// Ground-truth evaluation of localizer results: association of each result row with the ground
// truth, and along-track / cross-track / horizontal / vertical / 3-D errors per method.
//
// Errors of a frame, all in the evaluation's ENU frame (metres), with the route polyline R:
//  - along-track = s(estimate) - s(truth), s the along-route distance of the foot point on R
//    (Kyutoku et al.'s measure): positive = the estimate is ahead in the travel direction.
//  - cross-track = c(estimate) - c(truth), c the signed horizontal offset from R, positive to the
//    left of the travel direction.
//  - horizontal = |estimate - truth| in east/north; vertical = up(estimate) - up(truth);
//    3-D = |estimate - truth|.
//  - rotation = the angle (degrees) of the rotation between the estimated and the true camera
//    orientation (enu_from_cam, both moved into the evaluation's ENU axes), for rows and ground
//    truth that both carry one; NaN otherwise (such frames do not enter the rotation statistics).
// The truth is projected onto the part of R within `projection_window_m` of the s of the nearest
// ground-truth sample in time (itself projected in time order), the estimate onto the part within
// that window of the truth's s: a route passing the same place twice is handled.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "epiloc/eval/statistics.h"
#include "epiloc/eval/truth.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/result.h"

namespace epiloc {

enum class Association {
  kAuto,   // by frame when every ground-truth sample and every ok result row has a frame number
  kFrame,  // a row matches the ground-truth sample with its frame number (times not used: a
           // frame taken a few ms after its sample is compared with the sample as is)
  kTime,   // ground truth interpolated at the row's time (PositionTrack::Interpolate, max_gap_s)
};
// "auto", "frame", "time"; unknown names throw Error.
Association ParseAssociation(const std::string& name);
std::string AssociationName(Association association);

struct EvaluateOptions {
  Association association = Association::kAuto;  // how rows find their ground truth
  double max_gap_s = 0.25;             // time association: ground truth further away = unmatched
  double projection_window_m = 200.0;  // half-width of the route part projected onto, metres
  // A frame whose ground truth lies beyond the route's ends, or farther than this beside it, is
  // off the surveyed route: there `lost` or `off_route` is the right answer, and the counts
  // (MethodEvaluation::truth_off_route) keep such frames apart from those a method should
  // localize. 5 m: a lane's offset from the survey's line and the width of a carriageway.
  double on_route_m = 5.0;

  // Throws Error naming the invalid field.
  void Check() const;
};

// The route errors are measured along, in the ENU frame about `origin`.
struct EvaluationRoute {
  Geodetic origin;
  std::vector<Eigen::Vector3d> points_in_enu;  // travel order
  std::string source;                          // where it came from, for the report
};

// The errors of one evaluated frame (see the top of the file).
struct FrameError {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  Eigen::Vector3d truth_in_enu = Eigen::Vector3d::Zero();
  Eigen::Vector3d estimate_in_enu = Eigen::Vector3d::Zero();
  double truth_s_m = 0.0;
  double estimate_s_m = 0.0;
  double along_track_m = 0.0;
  double cross_track_m = 0.0;
  double horizontal_m = 0.0;
  double vertical_m = 0.0;
  double error_3d_m = 0.0;
  double rotation_deg = NAN;  // NaN when the row or the ground truth has no orientation
  // The row's own uncertainty (extra columns sigma_along_m, sigma_horizontal_m), NaN if none.
  double sigma_along_m = NAN;
  double sigma_horizontal_m = NAN;
};

// How honest a method's uncertainty is: the share of its evaluated frames whose error is within
// twice the standard deviation it reported (about 95 % for Gaussian errors and honest sigmas).
struct Calibration {
  int64_t count = 0;  // evaluated frames that carry a sigma
  double share_within_2_sigma = NAN;
};

struct MethodEvaluation {
  std::string method;
  int64_t rows = 0;                    // result rows of the method
  std::array<int64_t, 5> by_status{};  // rows per ResultStatus (index = enum value)
  int64_t unmatched = 0;               // ok rows without ground truth (outside max_gap_s / frame)
  std::vector<frame_t> unmatched_frames;  // their frame numbers (kInvalidFrame if none)
  std::vector<double> unmatched_times_s;  // their times
  std::vector<FrameError> frames;         // evaluated = ok and matched, by time
  // Rows with ground truth (any status), by where the truth is: on the surveyed route or off it
  // (EvaluateOptions::on_route_m), and how many of each have status ok.
  int64_t truth_on_route = 0, truth_off_route = 0;
  int64_t ok_on_route = 0, ok_off_route = 0;
  ErrorStatistics along_track, cross_track, horizontal, vertical, error_3d;
  ErrorStatistics rotation;       // degrees, over the frames with a rotation error (count may be 0)
  Calibration along_calibration;  // |along-track error| <= 2 sigma_along_m
  Calibration horizontal_calibration;  // horizontal error <= 2 sigma_horizontal_m

  int64_t ok() const { return by_status[static_cast<size_t>(ResultStatus::kOk)]; }
  int64_t not_localized() const { return rows - ok(); }
  int64_t evaluated() const { return static_cast<int64_t>(frames.size()); }
};

struct Evaluation {
  Association association = Association::kTime;  // the one used
  double max_gap_s = 0.0;
  EvaluationRoute route;
  double route_length_m = 0.0;
  std::vector<Eigen::Vector3d> truth_in_enu;                // every ground-truth sample, time order
  std::vector<double> truth_s_m;                            // their along-route distance
  std::vector<MethodEvaluation> methods;                    // in KnownMethods() order
  std::vector<std::pair<std::string, std::string>> inputs;  // (label, value) for the report
  std::vector<std::string> warnings;                        // also logged

  const MethodEvaluation* Find(const std::string& method) const;
};

// Evaluates every method of `result` against `truth` along `route`. Logs (and records) a warning
// per method with unmatched frames. Throws Error naming the result file when no ok row of any
// method finds ground truth (no overlap in time or frames).
Evaluation Evaluate(const ResultTable& result,
                    const PositionTrack& truth,
                    const EvaluationRoute& route,
                    const EvaluateOptions& options);

// Rows of method "gps" for `frames`: `gnss` interpolated at each frame's time
// (PositionTrack::Interpolate with `max_gap_s`), status lost where it has no position.
std::vector<ResultRow> GnssBaselineRows(const PositionTrack& gnss,
                                        const std::vector<FrameRecord>& frames,
                                        double max_gap_s);

// Routes: the ground-truth track (origin = first sample); a drive's ground truth; a route
// database's route and ENU origin. Throw Error naming the file when there is none.
EvaluationRoute RouteFromTrack(const PositionTrack& track);
EvaluationRoute RouteFromDrive(const std::string& drive_dir);
EvaluationRoute RouteFromDatabase(const std::string& db_path);

// The inputs of `epiloc evaluate`.
struct EvaluateInputs {
  std::string result_path;      // result CSV; empty = evaluate the GNSS of gnss_drive_dir alone
  std::string truth_path;       // ground truth (truth.h formats)
  TruthOptions truth;           // its format and frame
  std::string route_db_path;    // route from a database ...
  std::string route_drive_dir;  // ... or from a drive's ground truth; neither: the truth track
  std::string gnss_drive_dir;   // add the gps method from this drive's GNSS
  bool auto_gnss = true;        // ... or from the truth drive (truth is a drive directory) when
                                // the result has no gps rows
  EvaluateOptions evaluate;

  // Throws Error for contradictory or missing inputs.
  void Check() const;
};

// Reads everything, adds the gps baseline (see EvaluateInputs), and evaluates.
Evaluation EvaluateFiles(const EvaluateInputs& inputs);

}  // namespace epiloc
