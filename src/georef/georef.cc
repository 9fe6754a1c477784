#include "epiloc/georef/georef.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

const std::vector<std::string> kMethodNames = {"paper", "sim3", "piecewise"};

GeorefTransform MakeTransform(GeorefMethod method,
                              const std::vector<AnchorPair>& anchors,
                              const GeorefOptions& options) {
  switch (method) {
    case GeorefMethod::kPaper:
      return PaperTransform(anchors, options.paper_second_anchor);
    case GeorefMethod::kSim3:
      return Sim3Transform(anchors);
    case GeorefMethod::kPiecewise:
      return PiecewiseTransform(anchors, options.min_anchor_spacing_m, options.end_drift_reach_m);
  }
  Throw("unknown georeferencing method");
}

}  // namespace

std::string GeorefMethodName(GeorefMethod method) {
  return kMethodNames[static_cast<size_t>(method)];
}

GeorefMethod ParseGeorefMethod(const std::string& name) {
  for (size_t i = 0; i < kMethodNames.size(); ++i) {
    if (kMethodNames[i] == name) return static_cast<GeorefMethod>(i);
  }
  Throw("unknown georeferencing method '{}' (known: {}, all)", name, fmt::join(kMethodNames, ", "));
}

std::vector<GeorefMethod> ParseGeorefMethods(const std::string& list) {
  if (list == "all") return {GeorefMethod::kPaper, GeorefMethod::kSim3, GeorefMethod::kPiecewise};
  std::vector<GeorefMethod> methods;
  for (const std::string& name : SplitCsvLine(list)) {
    const GeorefMethod method = ParseGeorefMethod(Trim(name));
    if (std::find(methods.begin(), methods.end(), method) == methods.end()) {
      methods.push_back(method);
    }
  }
  EPILOC_CHECK(!methods.empty(), "--method: no method given");
  return methods;
}

void GeorefOptions::Check() const {
  EPILOC_CHECK(!methods.empty(), "georef: no method given");
  EPILOC_CHECK(max_gap_s > 0.0, "--max-gap-s must be > 0, got {}", max_gap_s);
  EPILOC_CHECK(paper_second_anchor == -1 || paper_second_anchor >= 1,
               "--paper-second-anchor must be -1 (last) or >= 1, got {}", paper_second_anchor);
  EPILOC_CHECK(min_anchor_spacing_m >= 0.0, "--min-anchor-spacing-m must be >= 0, got {}",
               min_anchor_spacing_m);
  EPILOC_CHECK(end_drift_reach_m >= 0.0, "--end-drift-reach-m must be >= 0, got {}",
               end_drift_reach_m);
}

GeorefResult Georeference(const ImportedTrajectory& trajectory,
                          const AnchorSet& anchors,
                          const std::vector<GeorefFrame>& frames,
                          const GeorefOptions& options) {
  options.Check();
  GeorefResult result;
  result.anchors_ok = static_cast<int64_t>(anchors.anchors.size());
  std::vector<const Anchor*> associated;
  std::vector<Rigid3d> vo_poses;
  for (const Anchor& anchor : anchors.anchors) {
    const auto pose = InterpolatePose(trajectory.poses, anchor.timestamp_s, options.max_gap_s);
    if (!pose) continue;
    associated.push_back(&anchor);
    vo_poses.push_back(*pose);
  }
  result.anchors_associated = static_cast<int64_t>(associated.size());
  if (associated.size() < 2) {
    Throw(
        "{}: {} of {} ok anchors fall within the trajectory {} ({} poses, {:.13g} .. {:.13g} s); "
        "need two (check the time offset)",
        anchors.path, associated.size(), anchors.anchors.size(), trajectory.path,
        trajectory.poses.size(), trajectory.poses.front().timestamp_s,
        trajectory.poses.back().timestamp_s);
  }
  result.origin = associated.front()->position;
  const EnuFrame enu(result.origin);
  std::vector<AnchorPair> pairs;
  for (size_t i = 0; i < associated.size(); ++i) {
    const Anchor& a = *associated[i];
    AnchorPair pair;
    pair.frame = a.frame;
    pair.timestamp_s = a.timestamp_s;
    pair.vo_from_cam = vo_poses[i];
    pair.centre_in_enu = enu.ToEnu(a.position);
    pair.scale_m_per_unit = a.scale_m_per_unit;
    pair.scale_drift_per_m = a.scale_drift_per_m;
    if (a.enu_from_cam) {
      pair.enu_from_cam =
          Eigen::Quaterniond(enu.EnuFromLocalEnu(a.position) * a.enu_from_cam->toRotationMatrix())
              .normalized();
    }
    pairs.push_back(pair);
  }

  std::vector<GeorefFrame> times = frames;
  if (times.empty()) {
    for (const StampedPose& pose : trajectory.poses)
      times.push_back({pose.frame, pose.timestamp_s});
  }
  result.table.path = trajectory.path;
  result.table.extra_columns = {"scale_m_per_unit"};
  for (const GeorefMethod method : options.methods) {
    const GeorefTransform transform = [&] {
      try {
        return MakeTransform(method, pairs, options);
      } catch (const Error& e) {
        Throw("{}: {}", anchors.path, e.what());  // name the anchor file the method could not use
      }
    }();
    GeorefMethodSummary summary;
    summary.method = method;
    summary.anchors_used = method == GeorefMethod::kPaper ? 2
                           : method == GeorefMethod::kSim3
                               ? static_cast<int>(pairs.size())
                               : static_cast<int>(transform.times.size());
    summary.min_scale = summary.max_scale = transform.intervals.front().scale;
    for (const Sim3d& sim : transform.intervals) {
      summary.min_scale = std::min(summary.min_scale, sim.scale);
      summary.max_scale = std::max(summary.max_scale, sim.scale);
    }
    double sum = 0.0;
    for (const AnchorPair& pair : pairs) {
      const double e =
          (transform.Map(pair.timestamp_s, pair.vo_from_cam).translation - pair.centre_in_enu)
              .norm();
      sum += e * e;
      summary.anchor_max_m = std::max(summary.anchor_max_m, e);
    }
    summary.anchor_rms_m = std::sqrt(sum / static_cast<double>(pairs.size()));
    for (const GeorefFrame& frame : times) {
      ResultRow row;
      row.frame = frame.frame;
      row.timestamp_s = frame.timestamp_s;
      row.method = GeorefMethodName(method);
      const auto vo = InterpolatePose(trajectory.poses, frame.timestamp_s, options.max_gap_s);
      if (!vo) {
        row.status = ResultStatus::kLost;
        row.extra = {""};
        ++summary.rows_lost;
        result.table.rows.push_back(row);
        continue;
      }
      double scale = 0.0;
      const Rigid3d enu_from_cam = transform.Map(frame.timestamp_s, *vo, &scale);
      row.status = ResultStatus::kOk;
      row.position = enu.ToGeodetic(enu_from_cam.translation);
      row.has_position = true;
      row.enu_from_cam = Eigen::Quaterniond(enu.EnuFromLocalEnu(row.position).transpose() *
                                            enu_from_cam.rotation.toRotationMatrix())
                             .normalized();
      row.extra = {FormatDouble(scale)};
      ++summary.rows_ok;
      result.table.rows.push_back(row);
    }
    result.methods.push_back(summary);
  }
  return result;
}

}  // namespace epiloc
