// Figures over a drive's structure anchors (structure_anchor.h): the median along-road sigma that
// `--structure auto` compares, and the VO's scale trend from the ok anchors' scales.
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "epiloc/anchor/structure_anchor.h"
#include "structure_anchor_internal.h"

namespace epiloc {

double MedianAlongSigma(const AnchorDriveResult& result) {
  std::vector<double> sigmas;
  for (const AnchorResult& a : result.frames) {
    if (a.has_pose && std::isfinite(a.along_sigma_m)) sigmas.push_back(a.along_sigma_m);
  }
  if (sigmas.empty()) return INFINITY;
  std::nth_element(sigmas.begin(), sigmas.begin() + sigmas.size() / 2, sigmas.end());
  return sigmas[sigmas.size() / 2];
}

std::optional<VoScaleTrend> ScaleTrendOfAnchors(const AnchorDriveResult& result,
                                                const std::function<int(frame_t)>& segment_of) {
  constexpr size_t kMinAnchors = 3;
  constexpr double kMinDistanceM = 10.0;
  std::vector<const AnchorResult*> ok;
  for (const AnchorResult& a : result.frames) {
    if (a.status == AnchorStatus::kOk && a.has_pose && std::isfinite(a.scale_m_per_unit) &&
        a.scale_m_per_unit > 0.0) {
      ok.push_back(&a);
    }
  }
  std::sort(ok.begin(), ok.end(),
            [](const AnchorResult* a, const AnchorResult* b) { return a->frame < b->frame; });
  // Per anchor: the distance travelled from the first (horizontal chords in frame order), the
  // log of its scale, its segment.
  struct Sample {
    double s = 0.0, log_scale = 0.0;
    int segment = 0;
  };
  std::vector<Sample> samples;
  double s = 0.0;
  for (size_t i = 0; i < ok.size(); ++i) {
    if (i > 0) {
      s += (ok[i]->map_from_cam.translation - ok[i - 1]->map_from_cam.translation).head<2>().norm();
    }
    samples.push_back(
        {s, std::log(ok[i]->scale_m_per_unit), segment_of ? segment_of(ok[i]->frame) : 0});
  }
  // Each segment's own mean taken out (its scale starts afresh), one slope over all: the pooled
  // within-segment least squares. A segment of one anchor tells nothing about the slope.
  std::map<int, std::pair<Eigen::Vector2d, int>> means;  // segment -> (sum, count)
  for (const Sample& p : samples) {
    auto& m = means.try_emplace(p.segment, Eigen::Vector2d::Zero(), 0).first->second;
    m.first += Eigen::Vector2d(p.s, p.log_scale);
    ++m.second;
  }
  std::vector<Eigen::Vector2d> centred;
  std::vector<const Sample*> used;
  double spread = 0.0;
  std::map<int, std::pair<double, double>> span;  // segment -> (first s, last s)
  for (const Sample& p : samples) {
    const auto& m = means.at(p.segment);
    if (m.second < 2) continue;
    centred.push_back(Eigen::Vector2d(p.s, p.log_scale) - m.first / m.second);
    used.push_back(&p);
    auto [it, inserted] = span.try_emplace(p.segment, p.s, p.s);
    it->second.second = p.s;
  }
  for (const auto& [segment, first_last] : span) spread += first_last.second - first_last.first;
  if (centred.size() < kMinAnchors || spread < kMinDistanceM) return std::nullopt;
  const std::optional<double> slope =
      structure_internal::LeastSquaresSlope(centred, kMinAnchors, 0.0);
  if (!slope) return std::nullopt;
  VoScaleTrend trend;
  trend.anchors = static_cast<int>(centred.size());
  trend.segments = static_cast<int>(span.size());
  trend.distance_m = spread;
  // The fitted line of the first and of the last anchor's segment at that anchor.
  const auto fitted = [&](const Sample* p) {
    const auto& m = means.at(p->segment);
    const Eigen::Vector2d mean = m.first / m.second;
    return std::exp(mean.y() + *slope * (p->s - mean.x()));
  };
  trend.first_scale = fitted(used.front());
  trend.last_scale = fitted(used.back());
  trend.percent_per_100m = 100.0 * 100.0 * *slope;
  return trend;
}

}  // namespace epiloc
