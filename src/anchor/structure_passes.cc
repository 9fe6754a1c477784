// The passes of structure anchoring over all anchors of a drive: the scale drift from the
// anchors' scales, and the consensus of neighbouring anchors (structure_anchor.h).
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <spdlog/spdlog.h>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "epiloc/geo/rigid3.h"
#include "structure_anchor_internal.h"

namespace epiloc {
namespace structure_internal {
namespace {

// The consensus pass's note in the message of an anchor it registered again.
constexpr const char* kConsensusNote = "re-registered from the consensus of its neighbours";

// The start of the fits' exchange's note in the message of an anchor it registered again.
constexpr const char* kExchangeNote = "registered from frame ";

// Appends a pass's note to an anchor's message ("; " between notes).
void AppendNote(const std::string& note, std::string* message) {
  *message = message->empty() ? note : *message + "; " + note;
}

// A posed anchor of the consensus pass.
struct Posed {
  size_t k;  // index into AnchorDriveResult::frames
  int pose;  // index into VoStructure::poses
};
struct Placements {
  Eigen::Vector2d median;
  std::vector<std::pair<Eigen::Vector2d, size_t>> each;  // placement, index into `anchors`
};

// The horizontal placements of anchor `i`'s camera by the similarities of the anchors around it
// (same segment, map centres within half the window; `i` itself included when include_self) and
// their median per axis; nullopt below three.
std::optional<Placements> PlaceByNeighbours(const std::vector<PlacedAnchor>& anchors,
                                            size_t i,
                                            bool include_self,
                                            double window_m) {
  const PlacedAnchor& a = anchors[i];
  Placements p;
  for (size_t j = 0; j < anchors.size(); ++j) {
    if (anchors[j].segment != a.segment || (j == i && !include_self)) continue;
    if ((anchors[j].map_centre - a.map_centre).head<2>().norm() > 0.5 * window_m) continue;
    p.each.push_back({anchors[j].Placing(a).head<2>(), j});
  }
  if (p.each.size() < 3) return std::nullopt;
  std::vector<double> xs, ys;
  for (const auto& e : p.each) {
    xs.push_back(e.first.x());
    ys.push_back(e.first.y());
  }
  std::nth_element(xs.begin(), xs.begin() + xs.size() / 2, xs.end());
  std::nth_element(ys.begin(), ys.begin() + ys.size() / 2, ys.end());
  p.median = Eigen::Vector2d(xs[xs.size() / 2], ys[ys.size() / 2]);
  return p;
}

// The horizontal direction of the road at anchor `i` in the map (unit): the VO path's tangent
// there turned by its similarity where the path is known, else the principal axis of the map
// centres of the neighbours that placed it (its own left out: it is the one judged).
Eigen::Vector2d RoadDirection(const std::vector<PlacedAnchor>& anchors,
                              size_t i,
                              const Placements& placements) {
  const PlacedAnchor& a = anchors[i];
  if (a.path && a.path_index >= 0 && a.path->size() >= 2) {
    const size_t n = a.path->size();
    const size_t at = static_cast<size_t>(a.path_index);
    const size_t before = at > 0 ? at - 1 : 0;
    const size_t after = std::min(at + 1, n - 1);
    const Eigen::Vector2d tangent =
        (a.map_from_world.rotation * ((*a.path)[after] - (*a.path)[before])).head<2>();
    if (tangent.norm() > 0.0) return tangent.normalized();
  }
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& e : placements.each) mean += anchors[e.second].map_centre.head<2>();
  mean /= static_cast<double>(placements.each.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& e : placements.each) {
    const Eigen::Vector2d d = anchors[e.second].map_centre.head<2>() - mean;
    scatter += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(scatter);
  return eigen.eigenvectors().col(1).normalized();
}

// The schedule's levels that free the scale (the finest level when none does).
std::vector<double> ScaleLevels(const StructureRegistrationOptions& registration) {
  std::vector<double> levels;
  for (const double d : registration.max_distances_m) {
    if (d <= registration.min_scale_distance_m) levels.push_back(d);
  }
  if (levels.empty()) levels.push_back(registration.max_distances_m.back());
  return levels;
}

// Whether an anchor's scale lies within max_scale_change of its GNSS seed's, as an ok anchor's
// must. A structure shrunk far below the seed's scale can put more of its points on the map's
// surfaces than the right one (synthetic street, KLT points, a drive's last window: scale 0.72
// times the seed's, 56 % of its points on the map against 51 %): the exchange neither offers nor
// takes such a fit.
bool ScaleAllowed(const AnchorResult& a, const StructureAnchorOptions& options) {
  return a.seed_scale_m_per_unit > 0.0 &&
         std::abs(a.scale_m_per_unit / a.seed_scale_m_per_unit - 1.0) <= options.max_scale_change;
}

// The anchors `redo` names (index into AnchorDriveResult::frames, restart) registered again, in
// parallel; one that gets no pose keeps its fit. The consensus pass's note goes into the message
// with `consensus_note`, and stays where the fit replaced carried it; so does the fits' exchange's.
void RegisterAgain(const DriveAnchoring& run,
                   const std::vector<std::pair<size_t, Restart>>& redo,
                   bool consensus_note,
                   AnchorDriveResult* out) {
  ParallelFor(static_cast<int64_t>(redo.size()), run.options.num_threads, [&](int64_t r) {
    const auto& [k, restart] = redo[static_cast<size_t>(r)];
    AnchorResult again = AnchorOne(run, run.indices[k], &restart);
    if (!again.has_pose) return;
    const AnchorResult& before = out->frames[k];
    again.seconds += before.seconds;
    // The exchange's note stays: the fit registered again came from that neighbour's.
    const size_t exchanged = before.message.find(kExchangeNote);
    if (exchanged != std::string::npos) {
      const size_t end = before.message.find("; ", exchanged);
      const std::string note = before.message.substr(
          exchanged, end == std::string::npos ? std::string::npos : end - exchanged);
      AppendNote(note, &again.message);
    }
    if (consensus_note || before.message.find(kConsensusNote) != std::string::npos) {
      AppendNote(kConsensusNote, &again.message);
    }
    out->frames[k] = again;
  });
}

// The anchors with a pose and a VO pose, in frame order.
std::vector<Posed> PosedAnchors(const std::vector<size_t>& indices,
                                const std::vector<int>& pose_of,
                                const AnchorDriveResult& out) {
  std::vector<Posed> posed;
  for (size_t k = 0; k < out.frames.size(); ++k) {
    const int pose = pose_of[indices[k]];
    if (out.frames[k].has_pose && pose >= 0) posed.push_back({k, pose});
  }
  return posed;
}

// The anchors of `posed` as the consensus pass sees them.
std::vector<PlacedAnchor> Place(const std::vector<Posed>& posed,
                                const VoStructure& vo,
                                const AnchorDriveResult& out) {
  auto path = std::make_shared<std::vector<Eigen::Vector3d>>();
  for (const auto& pose : vo.poses) path->push_back(pose.world_from_cam.translation);
  std::vector<PlacedAnchor> placed;
  for (const Posed& p : posed) {
    const AnchorResult& a = out.frames[p.k];
    const Rigid3d& world_from_cam = vo.poses[static_cast<size_t>(p.pose)].world_from_cam;
    PlacedAnchor one;
    one.map_from_world = ImpliedSimilarity(a, world_from_cam);
    one.vo_centre = world_from_cam.translation;
    one.map_centre = a.map_from_cam.translation;
    one.segment = vo.SegmentOf(a.frame);
    one.scale_drift_per_m = std::isfinite(a.scale_drift_per_m) ? a.scale_drift_per_m : 0.0;
    one.path = path;
    one.path_index = p.pose;
    placed.push_back(std::move(one));
  }
  return placed;
}

// The VO's scale drift at each posed anchor (ScaleDriftModel::kAcrossAnchors): the slope of the
// log of the anchors' scales (metres per VO unit) over their distance along the VO path (metres,
// at the anchor's scale), by least squares over the other anchors of its segment within half
// the window; 0 (none known) with fewer than three of them, spread over less than a quarter
// of the window, or a slope beyond max_scale_drift_per_m. The anchor's own scale is left out: it is
// the one the drift then corrects, and at a drive's end, where its window has cameras on one side
// only, it sat at the end of the regression and steepened it (KITTI frames 0 and 150 on the LiDAR's
// path: 0.31 and 0.37 m behind along the road with it, 0.08 m behind and 0.01 m ahead without). A
// window's scale is the drifting scale averaged over its structure: the average moves with the
// drift (the slope is the drift's), and no window's fit can trade a drift for a move along the road
// (as the per-window estimate does on a street of facades).
std::vector<double> DriftAcrossAnchors(const std::vector<Posed>& posed,
                                       const VoStructure& vo,
                                       const AnchorDriveResult& out,
                                       const StructureAnchorOptions& options) {
  std::vector<double> arc(vo.poses.size(), 0.0);
  for (size_t j = 1; j < vo.poses.size(); ++j) {
    arc[j] = arc[j - 1] +
             (vo.poses[j].world_from_cam.translation - vo.poses[j - 1].world_from_cam.translation)
                 .norm();
  }
  std::vector<double> drift(posed.size(), 0.0);
  const double limit = options.registration.max_scale_drift_per_m;
  for (size_t i = 0; i < posed.size(); ++i) {
    const AnchorResult& a = out.frames[posed[i].k];
    const int segment = vo.SegmentOf(a.frame);
    std::vector<Eigen::Vector2d> xy;  // (metres along the path from anchor i, log scale)
    for (const Posed& p : posed) {
      const AnchorResult& b = out.frames[p.k];
      if (p.k == posed[i].k) continue;  // its neighbours' scales only
      if (vo.SegmentOf(b.frame) != segment || !(b.scale_m_per_unit > 0.0)) continue;
      const double x =
          (arc[static_cast<size_t>(p.pose)] - arc[static_cast<size_t>(posed[i].pose)]) *
          a.scale_m_per_unit;
      if (std::abs(x) <= 0.5 * options.window_m) xy.push_back({x, std::log(b.scale_m_per_unit)});
    }
    // A slope beyond the limit is no usable VO's drift: the line does not hold there (none).
    const auto slope = LeastSquaresSlope(xy, 3, 0.25 * options.window_m);
    if (slope && std::abs(*slope) <= limit) drift[i] = *slope;
  }
  return drift;
}

// Each posed anchor registered again from its own fit, over the schedule's levels that free the
// scale, with the drift `drift` gives it (DriftAcrossAnchors over `posed`), and again without a
// drift; the drift is kept where it puts at least as many of the structure's points on the map's
// surfaces (within the finest distance) as the fit without it. The drift is a line through the
// neighbours' scales: where the VO's scale bends within a window (KITTI camera 0 on the LiDAR's
// path: flat over the first 15 m, then falling 3-4 % per 10 m), the line extrapolated to the
// drive's start warped the structure 5 % per 10 m, and the cameras, 20-50 m from much of their
// structure, landed 1.3-1.7 m behind along the road (scale 12-13 % high); warped so, the
// structure fits the map worse than unwarped (1416 against 1461 points on it at frame 0), while
// a drift that holds fits it better (camera 1: all but the last two of 16 anchors).
void RegisterWithDrift(const DriveAnchoring& run,
                       const std::vector<Posed>& posed,
                       const std::vector<double>& drift,
                       AnchorDriveResult* out) {
  const VoStructure& vo = run.vo;
  // The levels that free the scale: the drift changes the scale at the camera.
  const std::vector<double> levels = ScaleLevels(run.options.registration);
  std::vector<std::pair<size_t, Restart>> with_drift, without_drift;
  for (size_t i = 0; i < posed.size(); ++i) {
    const size_t k = posed[i].k;
    Restart restart;
    restart.sim = ImpliedSimilarity(out->frames[k],
                                    vo.poses[static_cast<size_t>(posed[i].pose)].world_from_cam);
    restart.levels_m = levels;
    without_drift.push_back({k, restart});
    restart.drift_per_m = drift[i];
    with_drift.push_back({k, restart});
  }
  std::vector<double> first_seconds(out->frames.size());
  for (size_t k = 0; k < out->frames.size(); ++k) first_seconds[k] = out->frames[k].seconds;
  AnchorDriveResult without = *out;
  RegisterAgain(run, with_drift, false, out);
  RegisterAgain(run, without_drift, false, &without);
  for (size_t i = 0; i < posed.size(); ++i) {
    const size_t k = posed[i].k;
    AnchorResult& a = out->frames[k];
    const AnchorResult& b = without.frames[k];
    if (drift[i] == 0.0 || !b.has_pose || a.num_inliers >= b.num_inliers) continue;
    const std::string note = fmt::format(
        "registered without the drift its neighbours give ({:+.2f} % per 10 m: {} of its points on "
        "the map against {})",
        1000.0 * drift[i], a.num_inliers, b.num_inliers);
    const double seconds = a.seconds + b.seconds - first_seconds[k];
    a = b;
    a.seconds = seconds;
    AppendNote(note, &a.message);
  }
}

}  // namespace

// The fits' exchange (StructureAnchorOptions::exchange_rounds).
void ExchangeFits(const DriveAnchoring& run, AnchorDriveResult* out) {
  const StructureAnchorOptions& options = run.options;
  const std::vector<double> levels = ScaleLevels(options.registration);
  // A neighbour's placement of the anchor's camera this far from its own is another basin: the
  // consensus pass's radius of agreement (the fine levels' reach).
  const double radius = options.consensus_radius_m;
  constexpr size_t kMaxBasins = 2;  // the placements tried per anchor and round
  for (int round = 0; round < options.exchange_rounds; ++round) {
    const std::vector<Posed> posed = PosedAnchors(run.indices, run.pose_of, *out);
    const std::vector<PlacedAnchor> placed = Place(posed, run.vo, *out);
    struct Trial {
      size_t k;       // index into out->frames
      size_t source;  // index into posed
      Restart restart;
      AnchorResult result;
    };
    std::vector<Trial> trials;
    for (size_t i = 0; i < posed.size(); ++i) {
      const AnchorResult& own = out->frames[posed[i].k];
      const bool own_allowed = ScaleAllowed(own, options);
      // The neighbours that fit their own windows better at a scale the GNSS allows (any that
      // does, when the anchor's own scale is not allowed), best first.
      std::vector<size_t> better;
      for (size_t j = 0; j < posed.size(); ++j) {
        if (j == i || placed[j].segment != placed[i].segment) continue;
        if (!ScaleAllowed(out->frames[posed[j].k], options)) continue;
        if ((placed[j].map_centre - placed[i].map_centre).head<2>().norm() >
            0.5 * options.window_m) {
          continue;
        }
        if (!own_allowed || out->frames[posed[j].k].inlier_share > own.inlier_share) {
          better.push_back(j);
        }
      }
      std::sort(better.begin(), better.end(), [&](size_t a, size_t b) {
        return out->frames[posed[a].k].inlier_share > out->frames[posed[b].k].inlier_share;
      });
      // One trial per basin they place the camera in, other than its own.
      std::vector<Eigen::Vector2d> basins;
      for (const size_t j : better) {
        if (basins.size() == kMaxBasins) break;
        const Eigen::Vector2d at = placed[j].Placing(placed[i]).head<2>();
        if ((at - placed[i].map_centre.head<2>()).norm() <= radius) continue;
        if (std::any_of(basins.begin(), basins.end(),
                        [&](const Eigen::Vector2d& b) { return (at - b).norm() <= radius; })) {
          continue;
        }
        basins.push_back(at);
        const double drift = out->frames[posed[j].k].scale_drift_per_m;
        trials.push_back({posed[i].k,
                          j,
                          {placed[j].map_from_world, std::isfinite(drift) ? drift : 0.0, levels},
                          {}});
      }
    }
    ParallelFor(static_cast<int64_t>(trials.size()), options.num_threads, [&](int64_t t) {
      Trial& trial = trials[static_cast<size_t>(t)];
      trial.result = AnchorOne(run, run.indices[trial.k], &trial.restart);
    });
    int changed = 0;
    for (const Trial& trial : trials) {
      AnchorResult& a = out->frames[trial.k];
      const AnchorResult& b = trial.result;
      a.seconds += b.seconds;
      if (!b.has_pose || !ScaleAllowed(b, options)) continue;
      if (ScaleAllowed(a, options) &&
          !FitsBetter(b.num_inliers, b.residual_m, a.num_inliers, a.residual_m)) {
        continue;
      }
      const std::string note =
          fmt::format("{}{}'s fit ({} of its points on the map against {})", kExchangeNote,
                      out->frames[posed[trial.source].k].frame, b.num_inliers, a.num_inliers);
      const double seconds = a.seconds;
      a = b;
      a.seconds = seconds;
      AppendNote(note, &a.message);
      ++changed;
    }
    spdlog::debug("structure anchors: exchange round {}: {} trials, {} of {} posed changed",
                  round + 1, trials.size(), changed, posed.size());
    if (changed == 0) break;
  }
}

// The consensus pass (StructureAnchorOptions::consensus_radius_m): each posed anchor's camera is
// placed by the similarities of the posed anchors around it (same segment, within half the window
// along the road); where most of them agree (within the radius of their median, at least three)
// and the anchor's own fit does not, it is registered again from the agreeing similarity nearest
// the median, with the fine levels only.
void ApplyConsensus(const DriveAnchoring& run, AnchorDriveResult* out) {
  const StructureAnchorOptions& options = run.options;
  const VoStructure& vo = run.vo;
  const std::vector<Posed> posed = PosedAnchors(run.indices, run.pose_of, *out);
  const std::vector<PlacedAnchor> placed = Place(posed, vo, *out);
  const double radius = options.consensus_radius_m;
  std::vector<std::pair<size_t, Restart>> redo;
  for (size_t i = 0; i < placed.size(); ++i) {
    const std::optional<Placements> p = PlaceByNeighbours(placed, i, true, options.window_m);
    if (!p) continue;
    int agreeing = 0;
    size_t nearest = i;
    double nearest_m = INFINITY;
    for (const auto& [at, j] : p->each) {
      const double d = (at - p->median).norm();
      if (d > radius) continue;
      ++agreeing;
      if (d < nearest_m) {
        nearest_m = d;
        nearest = j;
      }
    }
    if (agreeing < 3 || 2 * agreeing <= static_cast<int>(p->each.size())) continue;
    if ((placed[i].map_centre.head<2>() - p->median).norm() <= radius || nearest == i) continue;
    const double drift = out->frames[posed[i].k].scale_drift_per_m;
    redo.push_back({posed[i].k,
                    {placed[nearest].map_from_world, std::isfinite(drift) ? drift : 0.0,
                     options.refine_distances_m}});
  }
  RegisterAgain(run, redo, true, out);
  spdlog::debug("structure anchors: {} of {} posed re-registered from their neighbours' consensus",
                redo.size(), posed.size());
}

// An ok anchor whose neighbours' placements (itself left out) have their median beyond
// 2 max_along_sigma_m of it along the road, or of which no more than half lie within that, is
// not ok. Last: it judges the anchors as they are written.
void GateByNeighbours(const DriveAnchoring& run, AnchorDriveResult* out) {
  const StructureAnchorOptions& options = run.options;
  const VoStructure& vo = run.vo;
  const std::vector<Posed> posed = PosedAnchors(run.indices, run.pose_of, *out);

  // An anchor called ok claims its place along the road to 2 sigma = 2 max_along_sigma_m. Where
  // at least three posed neighbours place its camera (their similarities and the VO, the anchor
  // itself left out) and their median lies farther than that along the road, the claim does not
  // hold: an anchor can be sharp and wrong where the structure's error is shaped like a move
  // (KITTI with its track stretched to agree with the LiDAR: frames 0-20 called ok 0.55-1.44 m
  // off). Only the claim is tested: across the road the neighbours' placements carry their
  // rotation errors times the lever between the cameras (KITTI on the LiDAR's path: frames 90
  // and 100, 0.02 and 0.05 m off, placed 0.08 m across and 0.07-0.08 m along by neighbours
  // themselves 0.1 m off).
  // Nor does it where the median agrees but most placements do not (they scatter over metres:
  // the registrations have several minima along the street, e.g. a sparse map's facades or
  // parked and moving cars; synthetic street, other worlds than the tests': anchors called ok
  // 0.6 m and 5.2 m off whose neighbours placed them 0.5-3.9 m apart).
  const double claim_m = 2.0 * options.max_along_sigma_m;
  const std::vector<PlacedAnchor> placed = Place(posed, vo, *out);
  const std::vector<std::optional<double>> off = NeighbourDisagreement(placed, options.window_m);
  const std::vector<std::optional<double>> agree =
      NeighbourAgreement(placed, options.window_m, claim_m);
  for (size_t i = 0; i < posed.size(); ++i) {
    AnchorResult& a = out->frames[posed[i].k];
    if (a.status != AnchorStatus::kOk) continue;
    std::string note;
    if (off[i] && *off[i] > claim_m) {
      note = fmt::format(
          "its neighbours place it {:.2f} m away along the road, beyond its 2 sigma {:.2f} m",
          *off[i], claim_m);
    } else if (agree[i] && *agree[i] <= 0.5) {
      note = fmt::format(
          "only {:.0f} % of its neighbours place it within its 2 sigma {:.2f} m along the road",
          100.0 * *agree[i], claim_m);
    } else {
      continue;
    }
    a.status = AnchorStatus::kRejected;
    AppendNote(note, &a.message);
  }
}

// Each ok anchor moved horizontally to the median of its ok neighbours' placements (itself
// included; StructureAnchorOptions::consensus_placement). Last: the flags are the anchors' own.
void PlaceByConsensus(const DriveAnchoring& run, AnchorDriveResult* out) {
  std::vector<Posed> ok;
  for (const Posed& p : PosedAnchors(run.indices, run.pose_of, *out)) {
    if (out->frames[p.k].status == AnchorStatus::kOk) ok.push_back(p);
  }
  const std::vector<std::optional<Eigen::Vector2d>> centres =
      ConsensusCentres(Place(ok, run.vo, *out), run.options.window_m);
  for (size_t i = 0; i < ok.size(); ++i) {
    if (!centres[i]) continue;
    AnchorResult& a = out->frames[ok[i].k];
    a.consensus_move_m = MoveHorizontally(run, *centres[i], &a);
  }
}

// Two rounds. The first pass's scales are each window's scale averaged over its structure, and
// where the drift bends (or at a drive's end, where a window holds cameras on one side only) a
// line through them is not the drift at the anchor (KITTI camera 0: 0 and -4.9 % per 10 m where
// its truth gives -1.4 to -3.2). Registered with a drift, an anchor's scale is the scale at its
// camera (the warp's fixed point), so the line through its neighbours' scales after the first
// round is the drift's local slope. The second round registers each anchor again from its first
// pass's fit with that drift (from the first round's fits instead, the moves of the two rounds
// added up: camera 1 fell from 14 to 8-10 of 16 ok). KITTI on the LiDAR's path, four heading
// seeds: camera 0 5-6 -> 9-11 of 16 ok, median 0.17-0.27 -> 0.10 m; camera 1 11-14 -> 12-14.
void ApplyDriftAcrossAnchors(const DriveAnchoring& run, AnchorDriveResult* out) {
  const std::vector<Posed> posed = PosedAnchors(run.indices, run.pose_of, *out);
  const AnchorDriveResult first = *out;
  RegisterWithDrift(run, posed, DriftAcrossAnchors(posed, run.vo, first, run.options), out);
  // The second round's drift, from the first round's scales (a registration that gets no pose
  // keeps its fit: the posed anchors are the same).
  const std::vector<double> drift = DriftAcrossAnchors(posed, run.vo, *out, run.options);
  // The first round's time counts.
  std::vector<double> spent(out->frames.size());
  for (size_t k = 0; k < out->frames.size(); ++k) {
    spent[k] = out->frames[k].seconds - first.frames[k].seconds;
  }
  *out = first;
  RegisterWithDrift(run, posed, drift, out);
  for (size_t k = 0; k < out->frames.size(); ++k) out->frames[k].seconds += spent[k];
}

// The rotation consensus pass (StructureAnchorOptions::rotation_consensus).
// The structure is registered with the consensus over the longer radius, the camera turned by
// the one over the window (StructureAnchorOptions::placement_rotation_radius_m).
std::vector<std::optional<Eigen::Quaterniond>> ApplyRotationConsensus(const DriveAnchoring& run,
                                                                      AnchorDriveResult* out) {
  const StructureAnchorOptions& options = run.options;
  const VoStructure& vo = run.vo;
  const std::vector<Posed> posed = PosedAnchors(run.indices, run.pose_of, *out);
  const std::vector<PlacedAnchor> placed = Place(posed, vo, *out);
  const std::vector<Eigen::Quaterniond> placing =
      ConsensusRotations(placed, options.placement_rotation_radius_m);
  const std::vector<Eigen::Quaterniond> orienting = ConsensusRotations(placed, options.window_m);
  std::vector<std::optional<Eigen::Quaterniond>> orientations(out->frames.size());
  const std::vector<double> levels = ScaleLevels(options.registration);
  std::vector<std::pair<size_t, Restart>> redo;
  for (size_t i = 0; i < posed.size(); ++i) {
    const size_t k = posed[i].k;
    orientations[k] = orienting[i];
    // The camera stays where its own fit put it; the structure turns about it.
    Restart restart;
    restart.sim = placed[i].map_from_world;
    restart.sim.rotation = placing[i];
    restart.sim.translation =
        placed[i].map_centre - restart.sim.scale * (placing[i] * placed[i].vo_centre);
    const double drift = out->frames[k].scale_drift_per_m;
    restart.drift_per_m = std::isfinite(drift) ? drift : 0.0;
    restart.levels_m = levels;
    restart.hold_rotation = true;
    redo.push_back({k, restart});
  }
  // The consensus pass's note stays (the fit it started stays in place).
  RegisterAgain(run, redo, false, out);
  return orientations;
}

void OrientByConsensus(const DriveAnchoring& run,
                       const std::vector<std::optional<Eigen::Quaterniond>>& orientations,
                       AnchorDriveResult* out) {
  if (orientations.empty()) return;
  EPILOC_CHECK(orientations.size() == out->frames.size(),
               "OrientByConsensus: one orientation per result");
  for (const Posed& p : PosedAnchors(run.indices, run.pose_of, *out)) {
    if (!orientations[p.k]) continue;
    AnchorResult& a = out->frames[p.k];
    a.map_from_cam.rotation =
        (*orientations[p.k] * run.vo.poses[static_cast<size_t>(p.pose)].world_from_cam.rotation)
            .normalized();
    SetCentre(run.map_frame, a.map_from_cam.translation, &a);
  }
}

}  // namespace structure_internal

Eigen::Vector3d PlacedAnchor::Placing(const PlacedAnchor& other) const {
  if (scale_drift_per_m == 0.0 || !path || path != other.path || path_index < 0 ||
      other.path_index < 0) {
    return map_from_world * other.vo_centre;
  }
  // The path between the two cameras only, this anchor its pivot.
  const size_t first = static_cast<size_t>(std::min(path_index, other.path_index));
  const size_t last = static_cast<size_t>(std::max(path_index, other.path_index));
  const ScaleDriftPath between(
      std::vector<Eigen::Vector3d>(path->begin() + static_cast<std::ptrdiff_t>(first),
                                   path->begin() + static_cast<std::ptrdiff_t>(last) + 1),
      static_cast<size_t>(path_index) - first);
  return map_from_world * between.Camera(static_cast<size_t>(other.path_index) - first,
                                         scale_drift_per_m * map_from_world.scale);
}

std::vector<std::optional<double>> NeighbourDisagreement(const std::vector<PlacedAnchor>& anchors,
                                                         double window_m) {
  std::vector<std::optional<double>> off(anchors.size());
  for (size_t i = 0; i < anchors.size(); ++i) {
    if (const std::optional<structure_internal::Placements> p =
            structure_internal::PlaceByNeighbours(anchors, i, false, window_m)) {
      const Eigen::Vector2d road = structure_internal::RoadDirection(anchors, i, *p);
      off[i] = std::abs(road.dot(anchors[i].map_centre.head<2>() - p->median));
    }
  }
  return off;
}

std::vector<std::optional<double>> NeighbourAgreement(const std::vector<PlacedAnchor>& anchors,
                                                      double window_m,
                                                      double claim_m) {
  std::vector<std::optional<double>> share(anchors.size());
  for (size_t i = 0; i < anchors.size(); ++i) {
    if (const std::optional<structure_internal::Placements> p =
            structure_internal::PlaceByNeighbours(anchors, i, false, window_m)) {
      const Eigen::Vector2d road = structure_internal::RoadDirection(anchors, i, *p);
      int within = 0;
      for (const auto& [at, j] : p->each) {
        if (std::abs(road.dot(at - anchors[i].map_centre.head<2>())) <= claim_m) ++within;
      }
      share[i] = static_cast<double>(within) / static_cast<double>(p->each.size());
    }
  }
  return share;
}

std::vector<std::optional<Eigen::Vector2d>> ConsensusCentres(
    const std::vector<PlacedAnchor>& anchors, double window_m) {
  std::vector<std::optional<Eigen::Vector2d>> centres(anchors.size());
  for (size_t i = 0; i < anchors.size(); ++i) {
    if (const std::optional<structure_internal::Placements> p =
            structure_internal::PlaceByNeighbours(anchors, i, true, window_m)) {
      centres[i] = p->median;
    }
  }
  return centres;
}

std::vector<Eigen::Quaterniond> ConsensusRotations(const std::vector<PlacedAnchor>& anchors,
                                                   double window_m) {
  std::vector<Eigen::Quaterniond> out(anchors.size());
  for (size_t i = 0; i < anchors.size(); ++i) {
    std::vector<Eigen::Matrix3d> rotations;
    for (const PlacedAnchor& b : anchors) {
      if (b.segment != anchors[i].segment) continue;
      if ((b.map_centre - anchors[i].map_centre).head<2>().norm() > window_m) continue;
      rotations.push_back(b.map_from_world.rotation.toRotationMatrix());
    }
    // Weiszfeld's iteration for the point of least summed distance among the matrices, projected
    // onto the rotations at each step (chordal L1 mean), from their chordal mean.
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    for (const Eigen::Matrix3d& r : rotations) m += r;
    m = NearestRotation(m);
    for (int iteration = 0; iteration < 50; ++iteration) {
      Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
      double weights = 0.0;
      for (const Eigen::Matrix3d& r : rotations) {
        const double w = 1.0 / std::max((r - m).norm(), 1e-9);
        sum += w * r;
        weights += w;
      }
      const Eigen::Matrix3d next = NearestRotation(sum / weights);
      const double step = (next - m).norm();
      m = next;
      if (step < 1e-12) break;
    }
    out[i] = Eigen::Quaterniond(m).normalized();
  }
  return out;
}

}  // namespace epiloc
