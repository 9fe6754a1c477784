#include <algorithm>
#include <cmath>

#include "epiloc/core/error.h"
#include "epiloc/georef/georef.h"

namespace epiloc {
namespace {

// enu_from_vo implied by one anchor: R_k R_vo_k^T.
Eigen::Quaterniond AnchorRotation(const AnchorPair& anchor) {
  return (*anchor.enu_from_cam * anchor.vo_from_cam.rotation.conjugate()).normalized();
}

void RequireOrientations(const std::vector<AnchorPair>& anchors, const std::string& method) {
  for (const AnchorPair& a : anchors) {
    if (!a.enu_from_cam) {
      Throw("{}: the anchor of frame {} (t = {} s) has no orientation (qw,qx,qy,qz); {} needs it",
            method, a.frame, a.timestamp_s, method);
    }
  }
}

}  // namespace

Rigid3d GeorefTransform::Map(double timestamp_s, const Rigid3d& vo_from_cam, double* scale) const {
  size_t k = 0;
  if (intervals.size() > 1) {
    const auto it = std::upper_bound(times.begin(), times.end(), timestamp_s);
    const size_t after = static_cast<size_t>(it - times.begin());
    k = std::min(after > 0 ? after - 1 : 0, intervals.size() - 1);
  }
  const bool first = !times.empty() && timestamp_s < times.front();
  const bool last = !times.empty() && timestamp_s > times.back();
  const Sim3d& sim = first && before ? *before : last && after ? *after : intervals[k];
  if (scale) *scale = sim.scale;
  Eigen::Quaterniond enu_from_vo = sim.rotation;
  if (!rotations.empty()) {
    if (rotations.size() == 1 || timestamp_s <= times.front()) {
      enu_from_vo = rotations.front();
    } else if (timestamp_s >= times.back()) {
      enu_from_vo = rotations.back();
    } else {
      const double w = (timestamp_s - times[k]) / (times[k + 1] - times[k]);
      enu_from_vo = rotations[k].slerp(w, rotations[k + 1]);
    }
  }
  Eigen::Vector3d centre = sim * vo_from_cam.translation;
  const EndDrift* drift = first && before_drift ? &*before_drift
                          : last && after_drift ? &*after_drift
                                                : nullptr;
  if (drift) {
    // The relative scale r(x) = 1 + per_m clamp(x, -reach, reach) at x metres of road from the
    // anchor (negative before it), integrated from it: X = X_a + s R d (integral_0^x r) / x.
    const Eigen::Vector3d d = vo_from_cam.translation - drift->vo_anchor;
    const double x = (last ? 1.0 : -1.0) * sim.scale * d.norm();
    const double reach = drift->reach_m;
    const double held =
        std::abs(x) <= reach ? 0.5 * x * x : reach * std::abs(x) - 0.5 * reach * reach;
    const double mean = x == 0.0 ? 1.0 : 1.0 + drift->per_m * held / x;
    centre = sim * drift->vo_anchor + sim.scale * mean * (sim.rotation * d);
    if (scale) *scale = sim.scale * (1.0 + drift->per_m * std::clamp(x, -reach, reach));
  }
  if (!ramps.empty() && !first && !last) {
    // X = X_a + s R (integral_0^l r * chord + r(l) * (x - x_a - l chord)), r the relative scale.
    const Ramp& r = ramps[k];
    const Eigen::Vector3d d = vo_from_cam.translation - r.vo_start;
    const double l = std::clamp(d.dot(r.vo_chord) / r.vo_chord.squaredNorm(), 0.0, 1.0);
    const double at = r.start + (r.end - r.start) * l;
    const double integral = r.start * l + 0.5 * (r.end - r.start) * l * l;
    centre = r.enu_start +
             sim.scale * (sim.rotation * (integral * r.vo_chord + at * (d - l * r.vo_chord)));
    if (scale) *scale = sim.scale * at;
  }
  return Rigid3d((enu_from_vo * vo_from_cam.rotation).normalized(), centre);
}

GeorefTransform PaperTransform(const std::vector<AnchorPair>& anchors, int second_anchor) {
  EPILOC_CHECK(anchors.size() >= 2, "paper: needs two anchors, got {}", anchors.size());
  const int n = second_anchor < 0 ? static_cast<int>(anchors.size()) - 1 : second_anchor;
  EPILOC_CHECK(n >= 1 && n < static_cast<int>(anchors.size()),
               "paper: second anchor {} out of range [1, {}]", n, anchors.size() - 1);
  const AnchorPair& first = anchors.front();
  const AnchorPair& second = anchors[static_cast<size_t>(n)];
  RequireOrientations({first}, "paper");
  // Eq. 5: the VO axes unified with the map's at the first anchored keyframe.
  const Eigen::Quaterniond rotation = AnchorRotation(first);
  // Eq. 6, travel-direction component only: horizontal direction of the anchor chord.
  const Eigen::Vector3d chord = second.centre_in_enu - first.centre_in_enu;
  const Eigen::Vector3d horizontal(chord.x(), chord.y(), 0.0);
  EPILOC_CHECK(horizontal.norm() > 1e-3,
               "paper: the anchors of frames {} and {} are at the same horizontal position",
               first.frame, second.frame);
  const Eigen::Vector3d u = horizontal.normalized();
  const double vo_along =
      u.dot(rotation * (second.vo_from_cam.translation - first.vo_from_cam.translation));
  const double scale = u.dot(chord) / vo_along;
  EPILOC_CHECK(std::isfinite(scale) && scale > 0.0,
               "paper: the VO moved {} units along the anchors' travel direction between frames "
               "{} and {}; no positive scale",
               vo_along, first.frame, second.frame);
  // Eq. 7: X = s R (x - x_0) + X_0.
  Sim3d sim;
  sim.scale = scale;
  sim.rotation = rotation;
  sim.translation = first.centre_in_enu - scale * (rotation * first.vo_from_cam.translation);
  GeorefTransform transform;
  transform.intervals = {sim};
  return transform;
}

GeorefTransform Sim3Transform(const std::vector<AnchorPair>& anchors) {
  EPILOC_CHECK(anchors.size() >= 3, "sim3: needs at least three anchors, got {}", anchors.size());
  std::vector<Eigen::Vector3d> source, target;
  std::vector<Eigen::Quaterniond> rotations;
  for (const AnchorPair& a : anchors) {
    source.push_back(a.vo_from_cam.translation);
    target.push_back(a.centre_in_enu);
    if (a.enu_from_cam) rotations.push_back(AnchorRotation(a));
  }
  // With every anchor's orientation, the rotation fits those too (a nearly straight drive
  // leaves the roll about it to the positions' noise otherwise); without, Umeyama alone.
  const auto sim = rotations.size() == anchors.size() ? FitSim3(source, target, rotations)
                                                       : FitSim3(source, target);
  if (!sim) {
    Throw(
        "sim3: the {} anchors lie on one line in the VO frame; the rotation about it is not "
        "determined (use piecewise or paper)",
        anchors.size());
  }
  GeorefTransform transform;
  transform.intervals = {*sim};
  return transform;
}

GeorefTransform PiecewiseTransform(const std::vector<AnchorPair>& anchors,
                                   double min_anchor_spacing_m,
                                   double end_drift_reach_m) {
  RequireOrientations(anchors, "piecewise");
  std::vector<const AnchorPair*> kept;
  for (const AnchorPair& a : anchors) {
    if (!kept.empty() &&
        (a.centre_in_enu - kept.back()->centre_in_enu).norm() < min_anchor_spacing_m) {
      continue;
    }
    kept.push_back(&a);
  }
  EPILOC_CHECK(kept.size() >= 2,
               "piecewise: needs two anchors at least {} m apart, got {} of {} anchors",
               min_anchor_spacing_m, kept.size(), anchors.size());
  GeorefTransform transform;
  for (const AnchorPair* a : kept) {
    transform.times.push_back(a->timestamp_s);
    transform.rotations.push_back(AnchorRotation(*a));
  }
  for (size_t k = 0; k + 1 < kept.size(); ++k) {
    const AnchorPair& a = *kept[k];
    const AnchorPair& b = *kept[k + 1];
    const Eigen::Vector3d vo_chord = b.vo_from_cam.translation - a.vo_from_cam.translation;
    const Eigen::Vector3d enu_chord = b.centre_in_enu - a.centre_in_enu;
    if (vo_chord.norm() <= 1e-12 * (1.0 + a.vo_from_cam.translation.norm())) {
      Throw(
          "piecewise: the VO did not move between the anchors of frames {} and {} while the "
          "anchors are {:.2f} m apart",
          a.frame, b.frame, enu_chord.norm());
    }
    const Eigen::Quaterniond mean = transform.rotations[k].slerp(0.5, transform.rotations[k + 1]);
    const Eigen::Quaterniond fix = Eigen::Quaterniond::FromTwoVectors(mean * vo_chord, enu_chord);
    Sim3d sim;
    sim.scale = enu_chord.norm() / vo_chord.norm();
    sim.rotation = (fix * mean).normalized();
    sim.translation = a.centre_in_enu - sim.scale * (sim.rotation * a.vo_from_cam.translation);
    transform.intervals.push_back(sim);
  }
  // The anchors' own scales, where they are this trajectory's (the header).
  std::vector<double> ratios;
  for (size_t k = 0; k + 1 < kept.size(); ++k) {
    if (kept[k]->scale_m_per_unit && kept[k + 1]->scale_m_per_unit) {
      ratios.push_back(transform.intervals[k].scale /
                       (0.5 * (*kept[k]->scale_m_per_unit + *kept[k + 1]->scale_m_per_unit)));
    }
  }
  bool own_scales = false;
  double unit = 1.0;  // the anchors' scales times this are in the trajectory's units
  if (!ratios.empty()) {
    std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
    unit = ratios[ratios.size() / 2];
    constexpr double kMaxRatio = 1.25;
    own_scales = unit >= 1.0 / kMaxRatio && unit <= kMaxRatio;
  }
  if (own_scales) {
    for (size_t k = 0; k + 1 < kept.size(); ++k) {
      const AnchorPair& a = *kept[k];
      const AnchorPair& b = *kept[k + 1];
      GeorefTransform::Ramp ramp;
      ramp.vo_start = a.vo_from_cam.translation;
      ramp.vo_chord = b.vo_from_cam.translation - a.vo_from_cam.translation;
      ramp.enu_start = a.centre_in_enu;
      if (a.scale_m_per_unit && b.scale_m_per_unit) {
        const double mean = 0.5 * (*a.scale_m_per_unit + *b.scale_m_per_unit);
        ramp.start = *a.scale_m_per_unit / mean;
        ramp.end = *b.scale_m_per_unit / mean;
      }
      transform.ramps.push_back(ramp);
    }
  }
  // The ends: the end anchor's rotation, and its own scale in the trajectory's units (the
  // intervals' median ratio of chord to anchor scales; one interval's chord is noisier), else the
  // end interval's.
  const auto end_sim = [&](const AnchorPair& a, const Sim3d& interval,
                           const Eigen::Quaterniond& r) {
    Sim3d sim;
    sim.scale = own_scales && a.scale_m_per_unit ? unit * *a.scale_m_per_unit : interval.scale;
    sim.rotation = r;
    sim.translation = a.centre_in_enu - sim.scale * (sim.rotation * a.vo_from_cam.translation);
    return sim;
  };
  transform.before =
      end_sim(*kept.front(), transform.intervals.front(), transform.rotations.front());
  transform.after = end_sim(*kept.back(), transform.intervals.back(), transform.rotations.back());
  // And the end anchors' drifts, where their scales are this trajectory's: a drift is a VO's
  // own, and another trajectory's scale drifts elsewhere.
  const auto end_drift = [&](const AnchorPair& a) -> std::optional<GeorefTransform::EndDrift> {
    if (!own_scales || !a.scale_drift_per_m || *a.scale_drift_per_m == 0.0 ||
        end_drift_reach_m <= 0.0) {
      return std::nullopt;
    }
    return GeorefTransform::EndDrift{a.vo_from_cam.translation, *a.scale_drift_per_m,
                                     end_drift_reach_m};
  };
  transform.before_drift = end_drift(*kept.front());
  transform.after_drift = end_drift(*kept.back());
  return transform;
}

}  // namespace epiloc
