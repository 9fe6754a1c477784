// Georeferencing of a monocular trajectory (`epiloc georef`): the relative VO/SLAM poses are
// mapped into the local ENU frame with anchors (absolute poses of a few frames, anchors.h), by
// one of three methods, and written per frame as a result CSV (eval/result.h) that
// `epiloc evaluate` compares and `epiloc build-db --positions` accepts.
//
// Methods (x = VO camera centre, R_vo = VO world_from_cam rotation; anchor k: VO pose at its time
// (x_k, R_vo_k), absolute centre X_k and enu_from_cam R_k):
//  - paper (Kurobe et al., eq. 3-7): the first anchor fixes the rotation and the origin,
//    R = R_0 R_vo_0^T (eq. 5: the VO frame's axes unified with the map's), and the scale comes
//    from a second anchor n using only the travel-direction component (the paper's last
//    paragraph of "Transformation of the coordinate system"): with u the horizontal unit vector
//    of X_n - X_0, s = u.(X_n - X_0) / u.(R (x_n - x_0)) (eq. 6 restricted to u; vertical and
//    lateral parts of the VO chord do not bias the scale). X = s R (x - x_0) + X_0 (eq. 7, the
//    rotation being the first anchor's, as the text describes), enu_from_cam = R R_vo.
//    The second anchor is the last usable one by default (longest baseline).
//  - sim3: the least-squares similarity over all usable anchor centres (Umeyama); when every
//    anchor has an orientation, the rotation fits the anchors' R_j R_vo_j^T too (similarity.h),
//    so a nearly straight drive does not leave the roll about it to noise;
//    enu_from_cam = R R_vo. Needs >= 3 anchors, not on one line unless oriented.
//  - piecewise: between consecutive anchors k, k+1 a similarity that maps x_k to X_k and x_{k+1}
//    to X_{k+1} exactly: scale |X_{k+1} - X_k| / |x_{k+1} - x_k|, rotation = the mean of the two
//    anchors' rotations R_j R_vo_j^T (slerp at 1/2), corrected by the smallest rotation that
//    turns the VO chord onto the anchor chord. Positions are continuous at anchors and every
//    interval is re-anchored, so the VO's scale drift and rotation drift cannot accumulate past an
//    anchor. Orientation: slerp of the anchors' rotations R_j R_vo_j^T by time, times R_vo.
//    Anchors closer than `min_anchor_spacing_m` to the previous kept one are skipped (a chord that
//    short, e.g. when standing, gives no scale). Where the anchors carry their own scale of the
//    trajectory (structure anchors), the scale changes linearly inside each interval from one
//    anchor's to the next's (along the VO chord; their ratio only, the interval's mean scale the
//    chord's, so both anchors stay exact): a scale drifting by dk over an interval of length L
//    otherwise bends the positions by L dk / 8 in its middle. The anchors' scales are taken as
//    this trajectory's when the intervals' chord scales agree with them (median ratio within
//    1/1.25 .. 1.25; another VO's drift would not be this one's). Before the first and after the
//    last anchor the trajectory goes on from the end anchor with its own rotation R_j R_vo_j^T
//    and its own scale (in the trajectory's units: times the intervals' median ratio of chord
//    scale to the anchors' mean scale), else the end interval's: an interval's chord gives its
//    mean scale and the mean heading of its two anchors' positions, and a drifting VO's scale at
//    the drive's end is not the last interval's mean (shared KITTI drive, VO scale 7 % lower at
//    the end than over the last interval: 0.70 m off after 15 m, against 0.16 m). Optionally
//    (`end_drift_reach_m` > 0), where the end anchor also carries the VO's scale drift its fit
//    found (structure anchors' column scale_drift_per_m; this trajectory's scales only), the
//    scale goes on drifting so from it for that many metres and is held beyond
//    (GeorefTransform::EndDrift). Off by default: an anchor's drift is a line over its window,
//    not the drift at the drive's end. On the shared KITTI drive (VO falling 1.4-3.2 % per
//    10 m, flatter at both ends) with 20 m it helped where the ok anchors ended 19 m from the
//    drive's end (0.72 -> 0.23 m) and hurt where they end 10 m from it (7 of 8 runs of both
//    cameras: 0.14-0.27 -> 0.25-0.39 m).
// Anchors are associated with the trajectory by time (the VO pose interpolated at the anchor's
// time, InterpolatePose with max_gap_s); only status ok anchors are used. paper and piecewise need
// the anchors' orientations (qw..qz).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/georef/anchors.h"
#include "epiloc/georef/similarity.h"
#include "epiloc/georef/trajectory_import.h"
#include "epiloc/io/result.h"

namespace epiloc {

enum class GeorefMethod { kPaper, kSim3, kPiecewise };
// "paper", "sim3", "piecewise" (the result-CSV method names); unknown names throw Error.
std::string GeorefMethodName(GeorefMethod method);
GeorefMethod ParseGeorefMethod(const std::string& name);
// "all" or a comma-separated list of method names.
std::vector<GeorefMethod> ParseGeorefMethods(const std::string& list);

struct GeorefOptions {
  std::vector<GeorefMethod> methods = {GeorefMethod::kPiecewise};
  double max_gap_s = 1.0;             // VO poses further apart are not interpolated between
  int paper_second_anchor = -1;       // paper: index of the scale anchor among usable ones; -1 last
  double min_anchor_spacing_m = 1.0;  // piecewise: closer anchors are skipped
  // piecewise: the end anchors' drifts followed this far beyond them, metres (0: their scales
  // held). An anchor's fit measured its drift over its window (`epiloc anchor`'s structure
  // window, 40 m by default, holds the cameras within 20 m of it).
  double end_drift_reach_m = 0.0;

  // Throws Error naming the invalid field.
  void Check() const;
};

// An anchor associated with the trajectory, in the local ENU frame of GeorefResult::origin.
struct AnchorPair {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  Rigid3d vo_from_cam;  // VO pose at the anchor's time
  Eigen::Vector3d centre_in_enu = Eigen::Vector3d::Zero();
  std::optional<Eigen::Quaterniond> enu_from_cam;  // in the origin's ENU axes
  std::optional<double> scale_m_per_unit;          // the anchor's own (Anchor), if any
  std::optional<double> scale_drift_per_m;         // the anchor's drift (Anchor), if any
};

// A (piecewise) similarity from the VO frame to ENU: intervals between `times` (one Sim3d per
// interval, the first and last extended outwards) and, optionally, rotations per anchor time
// interpolated for the orientation. A single Sim3d is the one-interval case.
struct GeorefTransform {
  std::vector<double> times;     // anchor times (>= 2 for piecewise; empty for one Sim3d)
  std::vector<Sim3d> intervals;  // times.size() - 1 entries, or one
  std::vector<Eigen::Quaterniond> rotations;  // enu_from_vo per time (optional)
  // Before the first and after the last time, instead of the first and last interval (piecewise).
  std::optional<Sim3d> before, after;
  // Piecewise with the anchors' own scales: per interval, the scale relative to the interval's
  // (mean 1) at its first and last anchor, varying linearly along the VO chord between them
  // (empty: constant over every interval).
  struct Ramp {
    Eigen::Vector3d vo_start = Eigen::Vector3d::Zero();   // the first anchor's VO centre
    Eigen::Vector3d vo_chord = Eigen::Vector3d::Zero();   // to the second's
    Eigen::Vector3d enu_start = Eigen::Vector3d::Zero();  // the first anchor's centre
    double start = 1.0, end = 1.0;
  };
  std::vector<Ramp> ramps;
  // Piecewise with the anchors' own scales and drifts: beyond the end anchor the VO's scale
  // drifts as the end anchor's fit found it (relative change per metre of road, from the
  // anchor's time onwards), up to `reach_m` from the anchor and held beyond; the VO's step from
  // the anchor is taken as straight (the chord), so the scale applied at a pose is the one at its
  // distance from the anchor.
  struct EndDrift {
    Eigen::Vector3d vo_anchor = Eigen::Vector3d::Zero();  // the end anchor's VO centre
    double per_m = 0.0;
    double reach_m = 0.0;
  };
  std::optional<EndDrift> before_drift, after_drift;

  // ENU pose (enu_from_cam, centre in ENU) of a VO pose at time t, and the scale used there
  // (metres per VO unit).
  Rigid3d Map(double timestamp_s, const Rigid3d& vo_from_cam, double* scale = nullptr) const;
};

// The three methods on associated anchors (time order). Throw Error naming the problem (too few
// anchors, missing orientation, collinear anchors, a scale that is not positive).
GeorefTransform PaperTransform(const std::vector<AnchorPair>& anchors, int second_anchor = -1);
GeorefTransform Sim3Transform(const std::vector<AnchorPair>& anchors);
// Piecewise: the drive's ends follow the end anchors' drifts up to `end_drift_reach_m` from them
// (GeorefTransform::EndDrift; 0: the end anchors' scales held).
GeorefTransform PiecewiseTransform(const std::vector<AnchorPair>& anchors,
                                   double min_anchor_spacing_m = 1.0,
                                   double end_drift_reach_m = 0.0);

struct GeorefMethodSummary {
  GeorefMethod method = GeorefMethod::kPiecewise;
  int anchors_used = 0;    // anchors that define the transform
  double min_scale = 0.0;  // metres per VO unit over the intervals
  double max_scale = 0.0;
  double anchor_rms_m = 0.0;  // |mapped VO centre - anchor centre| over all associated anchors
  double anchor_max_m = 0.0;
  int64_t rows_ok = 0;
  int64_t rows_lost = 0;  // no VO pose at the row's time
};

struct GeorefResult {
  ResultTable table;               // rows per method (extra column scale_m_per_unit)
  Geodetic origin;                 // of the ENU frame used (the first associated anchor)
  int64_t anchors_ok = 0;          // status ok anchors in the file
  int64_t anchors_associated = 0;  // of them, with a VO pose at their time
  std::vector<GeorefMethodSummary> methods;
};

// Output times: one row per entry (e.g. the drive's frames); empty = one row per VO pose.
struct GeorefFrame {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
};

// Georeferences `trajectory` with `anchors` by every method of options.methods. Throws Error
// (naming the anchors file) when fewer than two anchors can be associated, and as above.
GeorefResult Georeference(const ImportedTrajectory& trajectory,
                          const AnchorSet& anchors,
                          const std::vector<GeorefFrame>& frames,
                          const GeorefOptions& options);

}  // namespace epiloc
