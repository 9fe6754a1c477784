// The Localizer's result rows: per tracked frame (gps, nearest, online, pnp) and the offline
// alignments over the recorded frames (dtw_fixed, fit_fixed, dtw_free, fit_free).
#include <cmath>

#include <spdlog/spdlog.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "localizer_internal.h"

namespace epiloc {
namespace {

// Columns of ExtraColumns(), by position.
enum Extra {
  kSigmaAlong,
  kSigmaHorizontal,
  kInliers,
  kPairsUsed,
  kRefine,
  kCrossTrack,
  kHeading,
  kRmse,
  kFlags,
  kNumExtra
};

ResultRow MakeRow(frame_t frame,
                  double timestamp_s,
                  const std::string& method,
                  ResultStatus status,
                  std::optional<double> s_m,
                  frame_t db_frame,
                  const std::optional<Geodetic>& position,
                  double sigma_along_m,
                  int inliers) {
  ResultRow r;
  r.frame = frame;
  r.timestamp_s = timestamp_s;
  r.method = method;
  r.status = status;
  if (status == ResultStatus::kOk) {
    r.has_position = position.has_value();
    if (position) r.position = *position;
    if (s_m) {
      r.has_s = true;
      r.s_m = *s_m;
    }
  }
  if (db_frame != kInvalidFrame) r.db_frame = db_frame;
  r.extra.assign(kNumExtra, "");
  if (std::isfinite(sigma_along_m)) r.extra[kSigmaAlong] = FormatFixed(sigma_along_m, 4);
  if (inliers >= 0) r.extra[kInliers] = std::to_string(inliers);
  return r;
}

// What the `flags` column says of a frame: evidence refused, a conflict, a re-initialisation.
std::string Flags(const FrameEstimate& est) {
  std::string flags;
  const auto add = [&](const char* flag) {
    if (!flags.empty()) flags += '|';
    flags += flag;
  };
  if (est.reinitialised) add("reinitialised");
  if (est.conflict) add("conflict");
  if (est.epipolar.valid && !est.epipolar_accepted) add("epipolar_refused");
  if (est.refined && est.refined->status == RefineStatus::kOk && !est.pnp_accepted) {
    add("pnp_refused");
  }
  if (!est.epipolar_accepted && !est.pnp_accepted) add("predicted");
  return flags;
}

// The status of a frame's rows that give no position.
ResultStatus NotLocalized(TrackStatus status) {
  switch (status) {
    case TrackStatus::kOffRoute:
      return ResultStatus::kOffRoute;
    case TrackStatus::kSkipped:
      return ResultStatus::kSkipped;
    default:
      return ResultStatus::kLost;
  }
}

}  // namespace

const std::vector<std::string>& Localizer::ExtraColumns() {
  static const std::vector<std::string> kColumns = {
      "sigma_along_m", "sigma_horizontal_m",   "inliers", "pairs_used", "refine", "cross_track_m",
      "heading_deg",   "reprojection_rmse_px", "flags"};
  return kColumns;
}

std::vector<ResultRow> Localizer::Rows(const FrameEstimate& est) const {
  const Impl& impl = *impl_;
  const LocalizeOptions& options = impl.options;
  std::vector<ResultRow> rows;
  if (options.all_methods) {
    if (est.gnss && est.gnss_on_route) {
      rows.push_back(MakeRow(est.frame, est.timestamp_s, "gps", ResultStatus::kOk,
                             est.gnss_on_route->s_m, kInvalidFrame, est.gnss, NAN, -1));
    } else {
      rows.push_back(MakeRow(est.frame, est.timestamp_s, "gps", NotLocalized(est.status),
                             std::nullopt, kInvalidFrame, std::nullopt, NAN, -1));
    }
    if (est.nearest_db_index >= 0) {
      const DbFrame& nearest = impl.db_frames[est.nearest_db_index];
      rows.push_back(MakeRow(est.frame, est.timestamp_s, "nearest", ResultStatus::kOk, nearest.s_m,
                             nearest.frame, nearest.position, NAN, est.nearest_inliers));
    } else {
      rows.push_back(MakeRow(est.frame, est.timestamp_s, "nearest", NotLocalized(est.status),
                             std::nullopt, kInvalidFrame, std::nullopt, NAN, -1));
    }
  }
  const bool ok = est.status == TrackStatus::kOk;
  if (options.all_methods || options.mode == LocalizeOptions::Mode::kOnline) {
    if (ok) {
      ResultRow r = MakeRow(est.frame, est.timestamp_s, "online", ResultStatus::kOk, est.s_m,
                            est.db_frame, est.position,
                            std::hypot(est.sigma_along_m, options.survey_sigma_m), est.num_inliers);
      r.extra[kPairsUsed] = std::to_string(est.epipolar.num_used);
      r.extra[kFlags] = Flags(est);
      rows.push_back(std::move(r));
    } else {
      rows.push_back(MakeRow(est.frame, est.timestamp_s, "online", NotLocalized(est.status),
                             std::nullopt, kInvalidFrame, std::nullopt, NAN, -1));
    }
  }
  if (!impl.refine) return rows;
  // pnp: the refined 6-DoF pose; where the structure is too thin, the pose disagrees with the
  // sequence or is too uncertain to place the frame, the online estimate, flagged in the `refine`
  // column.
  if (!ok || !est.refined) {
    rows.push_back(MakeRow(est.frame, est.timestamp_s, "pnp", NotLocalized(est.status),
                           std::nullopt, kInvalidFrame, std::nullopt, NAN, -1));
    return rows;
  }
  const PoseRefinement& ref = *est.refined;
  // A pose whose along-route sigma is beyond max_sigma_m places the frame no better than a track
  // that uncertain, which is reported lost (the same bound for both rows). The track took it in
  // with that weight and is the better estimate: a turn into the street, where the view runs
  // 60-70 degrees across the survey's and the evaluated pairs share some 30 points with it, gave
  // poses 0.4-0.5 m wrong with a sigma of 0.67 m.
  const bool uncertain = est.pnp_sigma_m > options.max_sigma_m;
  if (ref.status != RefineStatus::kOk || !est.pnp_accepted || uncertain) {
    // The online estimate, flagged: the pose was too thin, failed its checks, the track
    // refused it (it disagreed with better-supported evidence), or it is too uncertain.
    ResultRow r = MakeRow(est.frame, est.timestamp_s, "pnp", ResultStatus::kOk, est.s_m,
                          est.db_frame, est.position,
                          std::hypot(est.sigma_along_m, options.survey_sigma_m), ref.num_inliers);
    r.extra[kRefine] = ref.status != RefineStatus::kOk ? RefineStatusName(ref.status)
                       : !est.pnp_accepted             ? "refused"
                                                       : "uncertain";
    r.extra[kFlags] = Flags(est);
    rows.push_back(std::move(r));
    return rows;
  }
  const Eigen::Vector3d& centre = ref.enu_from_cam.translation;
  const Geodetic position = impl.enu.ToGeodetic(centre);
  ResultRow r = MakeRow(est.frame, est.timestamp_s, "pnp", ResultStatus::kOk, ref.projection.s_m,
                        est.db_frame, position, std::hypot(est.pnp_sigma_m, options.survey_sigma_m),
                        ref.num_inliers);
  const double floor = options.evidence.pnp_floor_sigma_m, survey = options.survey_sigma_m;
  // The horizontal sigma is the root of the 2x2 covariance's trace: the floor and the survey's
  // error, one-sigma per axis, enter it once for each of the two axes; the map's viewpoint error
  // once, across the route (LocalizeOptions::viewpoint_sigma_ratio).
  const double viewpoint = options.viewpoint_sigma_ratio * ref.projection.cross_track_m;
  r.extra[kSigmaHorizontal] =
      FormatFixed(std::sqrt(ref.sigma_horizontal_m * ref.sigma_horizontal_m +
                            2.0 * (floor * floor + survey * survey) + viewpoint * viewpoint),
                  4);
  r.extra[kFlags] = Flags(est);
  const Eigen::Matrix3d rotation = ref.enu_from_cam.rotation.toRotationMatrix();
  r.enu_from_cam =
      Eigen::Quaterniond(impl.enu.EnuFromLocalEnu(position).transpose() * rotation).normalized();
  const Eigen::Vector3d axis = rotation.col(2);
  double heading = std::atan2(axis.x(), axis.y()) * 180.0 / M_PI;
  if (heading < 0) heading += 360.0;
  r.extra[kRefine] = "ok";
  r.extra[kCrossTrack] = FormatFixed(ref.projection.cross_track_m, 3);
  r.extra[kHeading] = FormatFixed(heading, 3);
  r.extra[kRmse] = FormatFixed(ref.rmse_px, 3);
  rows.push_back(std::move(r));
  return rows;
}

std::vector<ResultRow> Localizer::OfflineRows() const {
  const Impl& impl = *impl_;
  const LocalizeOptions& options = impl.options;
  EPILOC_CHECK(options.record_offline,
               "localize: the offline alignments need LocalizeOptions::record_offline");
  const std::vector<RecordedFrame>& record = impl.record;
  const int num_frames = static_cast<int>(record.size());
  SparseCostMatrix costs(num_frames, impl.num_db_frames());
  int first = -1, last = -1;
  for (int i = 0; i < num_frames; ++i) {
    for (const auto& [j, cost] : RowCosts(record[i].valid_pairs)) costs.Set(i, j, cost);
    if (record[i].nearest >= 0) {
      if (first < 0) first = i;
      last = i;
    }
  }
  std::vector<ResultRow> rows;
  const auto align = [&](const std::string& dtw_name, const std::string& fit_name, bool fixed) {
    DtwResult path;
    if (first >= 0) {
      path = fixed ? AlignFixed(costs, record[first].nearest, record[last].nearest, options.dtw)
                   : AlignFree(costs, record[first].nearest, options.dtw);
      if (!path.valid) spdlog::warn("{} alignment failed: {}", dtw_name, path.failure);
    }
    for (int i = 0; i < num_frames; ++i) {
      const RecordedFrame& rec = record[i];
      const bool ok = path.valid && !rec.off_route && i >= first && (!fixed || i <= last) &&
                      path.db_index[i] >= 0;
      if (!ok) {
        for (const std::string& name : {dtw_name, fit_name}) {
          rows.push_back(
              MakeRow(rec.frame, rec.timestamp_s, name,
                      NotLocalized(rec.off_route ? TrackStatus::kOffRoute : TrackStatus::kLost),
                      std::nullopt, kInvalidFrame, std::nullopt, NAN, -1));
        }
        continue;
      }
      const int j = path.db_index[i];
      const DbFrame& match = impl.db_frames[j];
      int inliers = -1;
      for (const PairResult& p : rec.valid_pairs) {
        if (p.db_index == j) inliers = p.num_inliers;
      }
      rows.push_back(MakeRow(rec.frame, rec.timestamp_s, dtw_name, ResultStatus::kOk, match.s_m,
                             match.frame, match.position, NAN, inliers));
      VFitResult fit;
      const double s = impl.SubFramePosition(rec.valid_pairs, j, &fit);
      rows.push_back(MakeRow(rec.frame, rec.timestamp_s, fit_name, ResultStatus::kOk, s,
                             match.frame, impl.enu.ToGeodetic(impl.route.PointAt(s)), NAN,
                             fit.num_inliers));
    }
  };
  if (options.all_methods || options.mode == LocalizeOptions::Mode::kFixed) {
    align("dtw_fixed", "fit_fixed", true);
  }
  if (options.all_methods || options.mode == LocalizeOptions::Mode::kFree) {
    align("dtw_free", "fit_free", false);
  }
  return rows;
}

}  // namespace epiloc
