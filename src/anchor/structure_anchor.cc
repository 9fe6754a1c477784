#include "epiloc/anchor/structure_anchor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <utility>

#include <spdlog/spdlog.h>
#include <Eigen/Geometry>

#include "anchor_internal.h"
#include "epiloc/cloud/tiled_cloud.h"
#include "epiloc/cloud/voxel.h"
#include "epiloc/core/angles.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "structure_anchor_internal.h"

namespace epiloc {
namespace {

struct Fit {
  StructureRegistration registration;
  bool valid = false;
};

bool Better(const StructureRegistration& a, const StructureRegistration& b) {
  if (a.success != b.success) return a.success;
  return structure_internal::FitsBetter(a.num_inliers, a.rms_m, b.num_inliers, b.rms_m);
}

// The seed turned to the road's grade. The seed holds camera k level, so on a grade the seeded
// structure is tilted by the grade against the map (and by the camera's pitch on its mount, on
// any road). The window's seeded camera centres give the track's slope along the heading; the
// map's ground height beneath the same centres (GroundHeight) gives the road's. Beneath the
// seeded track, not beneath the GNSS fixes: the track is the VO's shape moved by the window's
// mean GNSS error, so its samples stay on one surface (road or pavement, parallel to it) where
// fixes scattered by the GNSS noise fall on both sides of a kerb. The seed is turned about the
// horizontal axis across the heading, through camera k, by the difference of the two angles.
// Unchanged when fewer than four cameras have ground beneath them or they span less than 5 m
// (a slope over a shorter base is the kerb's, not the road's).
Similarity3 SeedGrade(const VoStructure& vo,
                      const std::vector<int>& window,
                      int k,
                      const PointCloud& local,
                      const Eigen::Vector3d& along,
                      const Eigen::Vector3d& right,
                      const PriorOptions& prior,
                      const Similarity3& seed) {
  constexpr int kMaxSamples = 16;  // GroundHeight scans the local map once per sample
  constexpr double kMinSpreadM = 5.0;
  const Eigen::Vector3d pivot = seed * vo.poses[k].world_from_cam.translation;
  std::vector<Eigen::Vector2d> track, ground;
  const size_t step = std::max<size_t>(1, (window.size() + kMaxSamples - 1) / kMaxSamples);
  for (size_t i = 0; i < window.size(); i += step) {
    const Eigen::Vector3d c = seed * vo.poses[window[i]].world_from_cam.translation;
    const double s = (c - pivot).dot(along);
    track.emplace_back(s, c.z());
    if (const auto g = GroundHeight(local, c.head<2>(), prior)) ground.emplace_back(s, *g);
  }
  const auto track_slope = structure_internal::LeastSquaresSlope(track, 4, kMinSpreadM);
  const auto ground_slope = structure_internal::LeastSquaresSlope(ground, 4, kMinSpreadM);
  if (!track_slope || !ground_slope) return seed;
  const double angle = std::atan(*ground_slope) - std::atan(*track_slope);
  // A turn about `right` (along x up) by a positive angle lifts the road ahead.
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(angle, right));
  Similarity3 out = seed;
  out.rotation = (turn * seed.rotation).normalized();
  out.translation = turn * (seed.translation - pivot) + pivot;
  spdlog::debug("structure anchor: seed grade {:.2f} deg (road {:.2f}, track {:.2f})",
                angle / kDegToRad, std::atan(*ground_slope) / kDegToRad,
                std::atan(*track_slope) / kDegToRad);
  return out;
}

}  // namespace

void StructureAnchorOptions::Check() const {
  prior.Check();
  registration.Check();
  EPILOC_CHECK(std::isfinite(window_m) && window_m > 0, "structure anchor: window_m must be > 0");
  EPILOC_CHECK(std::isfinite(placement_rotation_radius_m) && placement_rotation_radius_m > 0,
               "structure anchor: placement_rotation_radius_m must be > 0");
  EPILOC_CHECK(exchange_rounds >= 0, "structure anchor: exchange_rounds must be >= 0");
  EPILOC_CHECK(auto_min_ok_share >= 0 && auto_min_ok_share <= 1,
               "structure anchor: auto_min_ok_share must be in [0, 1]");
  EPILOC_CHECK(std::isfinite(consensus_radius_m) && consensus_radius_m >= 0,
               "structure anchor: consensus_radius_m must be >= 0");
  EPILOC_CHECK(min_observations >= 2, "structure anchor: min_observations must be >= 2");
  EPILOC_CHECK(max_point_range_m > 0, "structure anchor: max_point_range_m must be > 0");
  EPILOC_CHECK(min_parallax_deg >= 0 && min_parallax_deg < 90,
               "structure anchor: min_parallax_deg must be in [0, 90)");
  EPILOC_CHECK(max_points >= registration.min_points,
               "structure anchor: max_points must be >= the registration's min_points");
  EPILOC_CHECK(map_voxel_m >= 0, "structure anchor: map_voxel_m must be >= 0");
  EPILOC_CHECK(map_margin_m > 0, "structure anchor: map_margin_m must be > 0");
  EPILOC_CHECK(min_inlier_share >= 0 && min_inlier_share <= 1,
               "structure anchor: min_inlier_share must be in [0, 1]");
  EPILOC_CHECK(max_rms_m > 0, "structure anchor: max_rms_m must be > 0");
  EPILOC_CHECK(max_scale_change > 0, "structure anchor: max_scale_change must be > 0");
  EPILOC_CHECK(min_along_information >= 0, "structure anchor: min_along_information must be >= 0");
  EPILOC_CHECK(max_along_sigma_m > 0, "structure anchor: max_along_sigma_m must be > 0");
  EPILOC_CHECK(gnss_sigma_m > 0 && max_prior_sigmas > 0,
               "structure anchor: gnss_sigma_m and max_prior_sigmas must be > 0");
  EPILOC_CHECK(max_height_offset_m > 0 && max_tilt_deg > 0,
               "structure anchor: max_height_offset_m and max_tilt_deg must be > 0");
  EPILOC_CHECK(heading_error_deg >= 0, "structure anchor: heading_error_deg must be >= 0");
  EPILOC_CHECK(num_threads >= 1, "structure anchor: num_threads must be >= 1");
  structure_internal::CheckMapBundleOptions(*this);
}

namespace {

// The similarity that maps `points` warped by `drift` (at the scale of `sim`) closest, in least
// squares, to where `sim` maps them unwarped; with `keep_rotation`, the one with sim's rotation
// (scale as fitted, translation through the centroids).
Similarity3 Rewarped(const std::vector<Eigen::Vector3d>& points,
                     const StructureDrift& drift,
                     const Similarity3& sim,
                     bool keep_rotation) {
  if (drift.per_m == 0.0 || points.size() < 3) return sim;
  const double kappa = drift.per_m * sim.scale;
  Eigen::Matrix3Xd from(3, points.size()), to(3, points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    from.col(static_cast<Eigen::Index>(i)) = points[i] + kappa * drift.directions[i];
    to.col(static_cast<Eigen::Index>(i)) = sim * points[i];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(from, to, true);
  Similarity3 out;
  out.scale = t.block<3, 1>(0, 0).norm();
  out.rotation = Eigen::Quaterniond(t.block<3, 3>(0, 0) / out.scale).normalized();
  out.translation = t.block<3, 1>(0, 3);
  if (keep_rotation) {
    out.rotation = sim.rotation;
    out.translation =
        to.rowwise().mean() - out.scale * (out.rotation * Eigen::Vector3d(from.rowwise().mean()));
  }
  return out;
}

}  // namespace

namespace structure_internal {

void SetCentre(const EnuFrame& map_frame, const Eigen::Vector3d& centre, AnchorResult* a) {
  a->map_from_cam.translation = centre;
  a->position = map_frame.ToGeodetic(centre);
  a->enu_from_cam = Eigen::Quaterniond(map_frame.EnuFromLocalEnu(a->position).transpose() *
                                       a->map_from_cam.rotation.toRotationMatrix())
                        .normalized();
}

std::optional<Eigen::Vector3d> GnssInMap(const DriveAnchoring& run, double t) {
  const auto s = run.drive.gnss.Interpolate(t, run.drive.max_gap_s);
  if (!s) return std::nullopt;
  return run.map_frame.ToEnu(s->position);
}

double MoveHorizontally(const DriveAnchoring& run, const Eigen::Vector2d& xy, AnchorResult* a) {
  Eigen::Vector3d centre = a->map_from_cam.translation;
  const double move = (xy - centre.head<2>()).norm();
  centre.head<2>() = xy;
  SetCentre(run.map_frame, centre, a);
  if (const auto gnss = GnssInMap(run, a->timestamp_s)) {
    a->prior_offset_m = (centre - *gnss).head<2>().norm();
  }
  return move;
}

AnchorResult AnchorOne(const DriveAnchoring& run, size_t index, const Restart* restart) {
  const Drive& drive = run.drive;
  const std::vector<int>& pose_of = run.pose_of;
  const VoStructure& vo = run.vo;
  const MapLoader& load = run.load;
  const EnuFrame& map_frame = run.map_frame;
  const StructureAnchorOptions& options = run.options;
  const Similarity3* given = restart ? &restart->sim : nullptr;
  const double drift_per_m = restart ? restart->drift_per_m : 0.0;
  const auto start = std::chrono::steady_clock::now();
  const FrameRecord& record = drive.frames[index];
  AnchorResult result;
  result.frame = record.frame;
  result.timestamp_s = record.timestamp_s;
  const auto finish = [&](AnchorResult& r) {
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return r;
  };
  const int k = pose_of[index];
  if (k < 0) {
    result.status = AnchorStatus::kLost;
    result.message = "no VO pose at the frame";
    return finish(result);
  }
  const auto gnss_k = GnssInMap(run, record.timestamp_s);
  if (!gnss_k) {
    result.status = AnchorStatus::kNoPrior;
    result.message = fmt::format("no GNSS position within {} s", drive.max_gap_s);
    return finish(result);
  }
  const int segment = vo.SegmentOf(record.frame);

  // The window: poses of the segment whose GNSS lies within window_m / 2 of the frame's.
  const double half = 0.5 * options.window_m;
  std::vector<int> window;
  std::vector<Eigen::Vector3d> window_gnss;
  const auto take = [&](int j) {
    if (vo.SegmentOf(vo.poses[j].frame) != segment) return false;
    const auto g = GnssInMap(run, vo.poses[j].timestamp_s);
    if (!g) return false;
    if ((*g - *gnss_k).head<2>().norm() > half) return false;
    window.push_back(j);
    window_gnss.push_back(*g);
    return true;
  };
  for (int j = k; j >= 0 && take(j); --j) {
  }
  std::reverse(window.begin(), window.end());
  std::reverse(window_gnss.begin(), window_gnss.end());
  for (int j = k + 1; j < static_cast<int>(vo.poses.size()) && take(j); ++j) {
  }
  Eigen::Vector2d gnss_mean = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < window.size(); ++i) {
    gnss_mean += window_gnss[i].head<2>();
  }
  gnss_mean /= std::max<size_t>(1, window.size());
  double gnss_spread = 0.0;
  for (size_t i = 0; i < window.size(); ++i) {
    gnss_spread += (window_gnss[i].head<2>() - gnss_mean).squaredNorm();
  }
  if (window.size() < 3 || gnss_spread < 1.0) {
    result.status = AnchorStatus::kNoPrior;
    result.message = "the window does not move (no scale from the GNSS)";
    return finish(result);
  }

  // The seed: the VO world levelled so that camera k is level and looks north, then the 2-D
  // similarity (turn, scale, shift) that takes the levelled VO centres onto the window's GNSS
  // positions by least squares: the heading comes from the whole window's track, which a slowly
  // varying GNSS error does not turn.
  const Rigid3d& world_from_cam = vo.poses[k].world_from_cam;
  const Eigen::Matrix3d level =
      MapFromCamRotation(0.0) * world_from_cam.rotation.conjugate().toRotationMatrix();
  std::vector<Eigen::Vector2d> levelled(window.size());
  Eigen::Vector2d levelled_mean = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < window.size(); ++i) {
    levelled[i] = (level * vo.poses[window[i]].world_from_cam.translation).head<2>();
    levelled_mean += levelled[i];
  }
  levelled_mean /= static_cast<double>(window.size());
  std::complex<double> cross(0.0, 0.0);
  double levelled_spread = 0.0;
  for (size_t i = 0; i < window.size(); ++i) {
    const Eigen::Vector2d a = levelled[i] - levelled_mean;
    const Eigen::Vector2d b = window_gnss[i].head<2>() - gnss_mean;
    cross += std::conj(std::complex<double>(a.x(), a.y())) * std::complex<double>(b.x(), b.y());
    levelled_spread += a.squaredNorm();
  }
  if (levelled_spread <= 0.0 || std::abs(cross) <= 0.0) {
    result.status = AnchorStatus::kNoPrior;
    result.message = "the window does not move horizontally";
    return finish(result);
  }
  // A counter-clockwise turn by theta is a compass heading of -theta.
  double heading = -std::arg(cross) / kDegToRad;
  if (options.heading_error_deg > 0) {
    std::mt19937_64 rng(options.seed * 7919ULL + static_cast<uint64_t>(record.frame));
    heading += std::uniform_real_distribution<double>(-options.heading_error_deg,
                                                      options.heading_error_deg)(rng);
  }
  Similarity3 seed;
  seed.scale = std::abs(cross) / levelled_spread;
  seed.rotation = Eigen::Quaterniond(MapFromCamRotation(heading) *
                                     world_from_cam.rotation.conjugate().toRotationMatrix())
                      .normalized();
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < window.size(); ++i) {
    offset +=
        window_gnss[i].head<2>() -
        (seed.scale * (seed.rotation * vo.poses[window[i]].world_from_cam.translation)).head<2>();
  }
  offset /= static_cast<double>(window.size());
  const double load_radius = half + options.max_point_range_m + options.map_margin_m;
  const PointCloud local = load(*gnss_k, load_radius);
  const auto ground = GroundHeight(local, gnss_k->head<2>(), options.prior);
  const double camera_z = ground ? *ground + options.prior.camera_height_m : gnss_k->z();
  const Eigen::Vector3d seeded_centre = seed.scale * (seed.rotation * world_from_cam.translation);
  seed.translation = Eigen::Vector3d(offset.x(), offset.y(), camera_z - seeded_centre.z());
  // The road's directions at the prior heading: along it and to its right, horizontal.
  const double h = heading * kDegToRad;
  const Eigen::Vector3d along(std::sin(h), std::cos(h), 0.0);
  const Eigen::Vector3d right(std::cos(h), -std::sin(h), 0.0);
  if (options.seed_grade) seed = SeedGrade(vo, window, k, local, along, right, options.prior, seed);
  result.has_prior = true;
  result.prior.frame = record.frame;
  result.prior.timestamp_s = record.timestamp_s;
  result.prior.heading_deg = heading;
  result.prior.position_in_map = seed * world_from_cam.translation;
  result.prior.has_ground = ground.has_value();
  result.prior.ground_z_m = ground.value_or(0.0);
  result.prior.map_from_cam =
      Rigid3d::FromMatrix(MapFromCamRotation(heading), result.prior.position_in_map);
  result.seed_scale_m_per_unit = seed.scale;

  // The structure: points of the segment seen inside a window, near its cameras; with each, its
  // drift direction along the segment's path (ScaleDriftPath, pivot camera k), from the path's
  // camera nearest the middle of the first and last keyframe that saw it.
  std::vector<Eigen::Vector3d> path_centres;
  std::vector<frame_t> path_frames;
  size_t path_pivot = 0;
  for (size_t j = 0; j < vo.poses.size(); ++j) {
    if (vo.poses[j].frame == kInvalidFrame || vo.SegmentOf(vo.poses[j].frame) != segment) continue;
    if (static_cast<int>(j) == k) path_pivot = path_centres.size();
    path_centres.push_back(vo.poses[j].world_from_cam.translation);
    path_frames.push_back(vo.poses[j].frame);
  }
  const ScaleDriftPath path(path_centres, path_pivot);
  const auto path_index = [&](double frame) {
    const auto it = std::lower_bound(path_frames.begin(), path_frames.end(), frame,
                                     [](frame_t f, double x) { return f < x; });
    if (it == path_frames.end()) return path_frames.size() - 1;
    const size_t i = static_cast<size_t>(it - path_frames.begin());
    return i > 0 && frame - path_frames[i - 1] < path_frames[i] - frame ? i - 1 : i;
  };
  struct Selected {
    std::vector<Eigen::Vector3d> points;
    StructureDrift drift;
  };
  // The registration with the rotation held places the camera: its points need their depth
  // (min_parallax_deg; a window with too few such points keeps them all).
  const bool placing = restart != nullptr && restart->hold_rotation;
  const auto select_with = [&](const std::vector<int>& poses, double max_range_vo,
                               double min_parallax_deg) {
    const frame_t frame_lo = vo.poses[poses.front()].frame;
    const frame_t frame_hi = vo.poses[poses.back()].frame;
    Selected selected;
    selected.drift.per_m = drift_per_m;
    selected.drift.estimate = options.scale_drift == ScaleDriftModel::kPerWindow && !given;
    for (const VoPoint& p : vo.points) {
      if (p.segment != segment || p.observations < options.min_observations) continue;
      if (p.last_frame < frame_lo || p.first_frame > frame_hi) continue;
      if (p.parallax_deg < min_parallax_deg) continue;  // NaN (not known): kept
      for (const int j : poses) {
        if ((p.point_in_world - vo.poses[j].world_from_cam.translation).norm() <= max_range_vo) {
          selected.points.push_back(p.point_in_world);
          const double middle = 0.5 * (static_cast<double>(p.first_frame) + p.last_frame);
          selected.drift.directions.push_back(path.Direction(p.point_in_world, path_index(middle)));
          break;
        }
      }
    }
    if (static_cast<int>(selected.points.size()) > options.max_points) {
      Selected kept;
      kept.drift.per_m = selected.drift.per_m;
      kept.drift.estimate = selected.drift.estimate;
      const double step = static_cast<double>(selected.points.size()) / options.max_points;
      for (int i = 0; i < options.max_points; ++i) {
        const size_t at = static_cast<size_t>(i * step);
        kept.points.push_back(selected.points[at]);
        kept.drift.directions.push_back(selected.drift.directions[at]);
      }
      selected = std::move(kept);
    }
    return selected;
  };
  const auto select_points = [&](const std::vector<int>& poses, double max_range_vo) {
    if (placing && options.min_parallax_deg > 0.0) {
      Selected deep = select_with(poses, max_range_vo, options.min_parallax_deg);
      if (static_cast<int>(deep.points.size()) >= options.registration.min_points) return deep;
    }
    return select_with(poses, max_range_vo, 0.0);
  };
  const Selected structure = select_points(window, options.max_point_range_m / seed.scale);
  const std::vector<Eigen::Vector3d>& points = structure.points;
  const bool with_drift = options.scale_drift != ScaleDriftModel::kNone;
  const StructureDrift* drift = with_drift ? &structure.drift : nullptr;
  result.structure_points = static_cast<int>(points.size());
  if (static_cast<int>(points.size()) < options.registration.min_points) {
    result.status = AnchorStatus::kLost;
    result.message = fmt::format("{} VO points in the window, need {}", points.size(),
                                 options.registration.min_points);
    return finish(result);
  }

  // The map around the seeded structure.
  Bounds3f bounds;
  for (const Eigen::Vector3d& p : points) bounds.Extend((seed * p).cast<float>());
  const float margin = static_cast<float>(options.map_margin_m);
  PointCloud cropped;
  for (const Eigen::Vector3f& q : local.positions) {
    if ((q.array() >= bounds.min.array() - margin).all() &&
        (q.array() <= bounds.max.array() + margin).all()) {
      cropped.positions.push_back(q);
    }
  }
  if (cropped.size() < 100) {
    result.status = AnchorStatus::kNoCoverage;
    result.message = fmt::format("{} map points around the structure", cropped.size());
    return finish(result);
  }
  StructureMap structure_map(cropped, options.registration);
  StructureRegistration best;
  bool have = false;
  std::vector<Eigen::Vector2d> offsets = {Eigen::Vector2d::Zero()};
  offsets.insert(offsets.end(), options.seed_offsets_m.begin(), options.seed_offsets_m.end());
  if (given) {
    // From a given similarity, no search.
    StructureRegistrationOptions fine = options.registration;
    fine.search_step_m = 0.0;
    fine.max_distances_m = restart->levels_m;
    fine.hold_rotation = restart->hold_rotation;
    if (restart->hold_rotation) fine.profile_moves = 0;
    // Under a drift the structure changes shape: the start is the similarity that takes the
    // warped points where `given` takes the points (least squares).
    const Similarity3 start =
        drift ? Rewarped(points, *drift, *given, restart->hold_rotation) : *given;
    best = RegisterStructure(points, structure_map, start, along, fine, drift);
    have = true;
    offsets.clear();
  }
  for (const Eigen::Vector2d& o : offsets) {
    Similarity3 start_sim = seed;
    start_sim.translation += o.x() * along + o.y() * right;
    const StructureRegistration fit =
        RegisterStructure(points, structure_map, start_sim, along, options.registration, drift);
    if (!have || Better(fit, best)) {
      best = fit;
      have = true;
    }
  }
  // Refinement over a shorter window about the frame: less of the VO's scale drift.
  if (best.success && options.refine_window_m > 0.0) {
    const double refine_half_vo = 0.5 * options.refine_window_m / best.map_from_world.scale;
    std::vector<int> near;
    for (const int j : window) {
      if ((vo.poses[j].world_from_cam.translation - world_from_cam.translation).norm() <=
          refine_half_vo) {
        near.push_back(j);
      }
    }
    const Selected refine_structure =
        select_points(near, options.max_point_range_m / best.map_from_world.scale);
    const std::vector<Eigen::Vector3d>& refine_points = refine_structure.points;
    StructureRegistrationOptions refine = options.registration;
    refine.search_step_m = 0.0;
    refine.max_distances_m = options.refine_distances_m;
    const StructureRegistration refined =
        RegisterStructure(refine_points, structure_map, best.map_from_world, along, refine,
                          with_drift ? &refine_structure.drift : nullptr);
    if (refined.success) {
      best = refined;
      result.structure_points = static_cast<int>(refine_points.size());
    }
  }
  spdlog::debug(
      "structure anchor frame {}: {} points, seed search moved {:.2f} {:.2f} m, turned {:.1f} "
      "deg; {} iterations, share {:.2f}, residual {:.3f} m, scale {:.4f} (seed {:.4f}), drift "
      "{:.2f} % per 10 m",
      record.frame, points.size(), best.search_offset_m.x(), best.search_offset_m.y(),
      best.search_yaw_deg, best.iterations, best.inlier_share, best.rms_m,
      best.map_from_world.scale, seed.scale, 1000.0 * best.scale_drift_per_m);
  result.num_inliers = best.num_inliers;
  result.inlier_share = best.inlier_share;
  result.residual_m = best.rms_m;
  result.along_information = best.along_information;
  result.along_sigma_m = best.along_sigma_m;
  result.scale_drift_per_m = best.scale_drift_per_m;
  result.rounds = best.iterations;
  result.rmse_px = NAN;
  if (!best.success) {
    result.status = AnchorStatus::kLost;
    result.message = best.message;
    return finish(result);
  }
  const Similarity3& sim = best.map_from_world;
  result.scale_m_per_unit = sim.scale;
  result.has_pose = true;
  result.map_from_cam.rotation = sim.rotation * world_from_cam.rotation;
  const Eigen::Vector3d centre = sim * world_from_cam.translation;
  SetCentre(map_frame, centre, &result);
  result.prior_offset_m = (centre - *gnss_k).head<2>().norm();
  if (const auto g = GroundHeight(local, centre.head<2>(), options.prior)) {
    result.height_above_ground_m = centre.z() - *g;
  }

  // Reliability.
  std::string& why = result.message;
  const auto [pitch, roll] =
      anchor_internal::PitchRollDeg(result.map_from_cam.rotation.toRotationMatrix());
  const double scale_change = sim.scale / seed.scale - 1.0;
  if (best.inlier_share < options.min_inlier_share) {
    why = fmt::format("inlier share {:.2f} below {:.2f}", best.inlier_share,
                      options.min_inlier_share);
  } else if (best.rms_m > options.max_rms_m) {
    why = fmt::format("residual {:.3f} m above {:.3f} m", best.rms_m, options.max_rms_m);
  } else if (std::abs(scale_change) > options.max_scale_change) {
    why = fmt::format("scale {:+.0f} % from the GNSS's, more than {:.0f} %", 100 * scale_change,
                      100 * options.max_scale_change);
  } else if (best.along_information < options.min_along_information ||
             best.along_sigma_m > options.max_along_sigma_m) {
    why = fmt::format("weak along the road (information {:.3f}, sigma {:.3f} m)",
                      best.along_information, best.along_sigma_m);
  } else if (result.prior_offset_m > options.max_prior_sigmas * options.gnss_sigma_m) {
    why = fmt::format("{:.1f} m from the GNSS prior, more than {:.0f} sigma", result.prior_offset_m,
                      options.max_prior_sigmas);
  } else if (std::isfinite(result.height_above_ground_m) &&
             std::abs(result.height_above_ground_m - options.prior.camera_height_m) >
                 options.max_height_offset_m) {
    why = fmt::format("camera {:.2f} m above the map's ground, expected {:.2f} +- {:.2f} m",
                      result.height_above_ground_m, options.prior.camera_height_m,
                      options.max_height_offset_m);
  } else if (std::abs(pitch) > options.max_tilt_deg || std::abs(roll) > options.max_tilt_deg) {
    why = fmt::format("camera tilted (pitch {:.1f}, roll {:.1f} deg)", pitch, roll);
  }
  result.status = why.empty() ? AnchorStatus::kOk : AnchorStatus::kRejected;
  return finish(result);
}

// The similarity VO world -> map an anchored frame's pose implies.
std::optional<double> LeastSquaresSlope(const std::vector<Eigen::Vector2d>& xy,
                                        size_t min_samples,
                                        double min_spread) {
  if (xy.empty() || xy.size() < min_samples) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double lo = INFINITY, hi = -INFINITY;
  for (const Eigen::Vector2d& p : xy) {
    mean += p;
    lo = std::min(lo, p.x());
    hi = std::max(hi, p.x());
  }
  mean /= static_cast<double>(xy.size());
  if (hi - lo < min_spread) return std::nullopt;
  double sxx = 0.0, sxy = 0.0;
  for (const Eigen::Vector2d& p : xy) {
    sxx += (p.x() - mean.x()) * (p.x() - mean.x());
    sxy += (p.x() - mean.x()) * (p.y() - mean.y());
  }
  if (sxx <= 0.0) return std::nullopt;
  return sxy / sxx;
}

Similarity3 ImpliedSimilarity(const AnchorResult& a, const Rigid3d& world_from_cam) {
  Similarity3 s;
  s.scale = a.scale_m_per_unit;
  s.rotation = (a.map_from_cam.rotation * world_from_cam.rotation.conjugate()).normalized();
  s.translation = a.map_from_cam.translation - s.scale * (s.rotation * world_from_cam.translation);
  return s;
}

}  // namespace structure_internal

namespace {

int CountOk(const AnchorDriveResult& result) {
  return static_cast<int>(
      std::count_if(result.frames.begin(), result.frames.end(),
                    [](const AnchorResult& a) { return a.status == AnchorStatus::kOk; }));
}

// AnchorDriveByStructure, and with `alternative`, AnchorDriveByStructureAuto.
AnchorDriveResult AnchorByStructure(const AnchorInputs& inputs,
                                    const VoStructure& vo,
                                    const std::function<VoStructure()>* alternative,
                                    const StructureAnchorOptions& options,
                                    const ProgressCallback& progress,
                                    StructureChoice* choice) {
  const auto start = std::chrono::steady_clock::now();
  inputs.Check();
  options.Check();
  const Drive drive = LoadDrive(inputs.drive_dir);
  if (drive.gnss.samples.empty()) {
    Throw("{}: the drive has no GNSS positions to anchor from", inputs.drive_dir);
  }
  const std::vector<size_t> indices = anchor_internal::SelectFrames(inputs, drive);
  const auto on_frames = [&](const VoStructure& structure, std::vector<int>* pose_of) {
    VoStructure timed = structure.OnFramesOf(drive, pose_of);
    if (std::none_of(pose_of->begin(), pose_of->end(), [](int k) { return k >= 0; })) {
      Throw("{}: no VO pose falls on a frame time of drive {} (another drive?)", inputs.vo_path,
            inputs.drive_dir);
    }
    return timed;
  };
  std::vector<int> pose_of;
  VoStructure timed = on_frames(vo, &pose_of);
  const std::unique_ptr<TiledCloud> map =
      anchor_internal::OpenMap(inputs.cloud_path, inputs.tile_dir, inputs.max_whole_points);
  const EnuFrame map_frame(inputs.map_origin);
  anchor_internal::CheckMapNearDrive(inputs.cloud_path, *map, map_frame, drive,
                                     inputs.max_map_distance_m);
  AnchorDriveResult out;
  out.drive_name = drive.name;
  out.frames.resize(indices.size());
  std::mutex progress_mutex;
  // The map around the whole run, voxel-filtered once, when that is not too large; else each
  // frame loads (and filters) its own neighbourhood.
  const double load_radius =
      0.5 * options.window_m + options.max_point_range_m + options.map_margin_m;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> positions;
  for (const size_t i : indices) {
    if (const auto g = drive.gnss.Interpolate(drive.frames[i].timestamp_s, drive.max_gap_s)) {
      positions.push_back(map_frame.ToEnu(g->position));
      centre += positions.back();
    }
  }
  double run_radius = INFINITY;
  if (!positions.empty()) {
    centre /= static_cast<double>(positions.size());
    run_radius = 0.0;
    for (const Eigen::Vector3d& p : positions) {
      run_radius = std::max(run_radius, (p - centre).head<2>().norm());
    }
  }
  PointCloud shared;
  const bool share = run_radius + load_radius <= options.max_shared_radius_m;
  if (share) {
    shared = map->Load(centre, run_radius + load_radius);
    shared.intensity.clear();
    shared.rgb.clear();
    if (options.map_voxel_m > 0) shared = VoxelFilter(shared, options.map_voxel_m);
  }
  std::mutex load_mutex;
  const structure_internal::MapLoader load = [&](const Eigen::Vector3d& at, double radius) {
    if (share) {
      PointCloud near;
      const float r2 = static_cast<float>(radius * radius);
      for (const Eigen::Vector3f& p : shared.positions) {
        if ((p.head<2>() - at.head<2>().cast<float>()).squaredNorm() <= r2) {
          near.positions.push_back(p);
        }
      }
      return near;
    }
    PointCloud near;
    {
      std::lock_guard<std::mutex> lock(load_mutex);
      near = map->Load(at, radius);
    }
    near.intensity.clear();
    near.rgb.clear();
    return options.map_voxel_m > 0 ? VoxelFilter(near, options.map_voxel_m) : near;
  };
  // The first pass: each frame from the GNSS seed.
  const auto first_pass = [&](const structure_internal::DriveAnchoring& run,
                              const ProgressCallback& report) {
    AnchorDriveResult first = out;
    int64_t done = 0;
    ParallelFor(static_cast<int64_t>(indices.size()), options.num_threads, [&](int64_t k) {
      first.frames[static_cast<size_t>(k)] =
          structure_internal::AnchorOne(run, indices[static_cast<size_t>(k)]);
      std::lock_guard<std::mutex> lock(progress_mutex);
      ++done;
      if (report) report(done, static_cast<int64_t>(indices.size()));
    });
    return first;
  };
  out = first_pass({drive, indices, pose_of, timed, load, map_frame, options}, progress);
  // The passes after the first (structure_anchor.h, step 5).
  const auto passes = [&](const structure_internal::DriveAnchoring& run, AnchorDriveResult* r) {
    if (options.exchange_rounds > 0) structure_internal::ExchangeFits(run, r);
    if (options.scale_drift == ScaleDriftModel::kAcrossAnchors) {
      structure_internal::ApplyDriftAcrossAnchors(run, r);
    }
    if (options.consensus_radius_m > 0.0) structure_internal::ApplyConsensus(run, r);
    std::vector<std::optional<Eigen::Quaterniond>> orientations;
    if (options.rotation_consensus) {
      orientations = structure_internal::ApplyRotationConsensus(run, r);
    }
    if (options.consensus_radius_m > 0.0) structure_internal::GateByNeighbours(run, r);
    if (options.consensus_placement) structure_internal::PlaceByConsensus(run, r);
    structure_internal::OrientByConsensus(run, orientations, r);
    if (options.map_bundle) structure_internal::RefineByMapBundle(run, r);
  };
  const structure_internal::DriveAnchoring run{drive, indices,   pose_of, timed,
                                               load,  map_frame, options};
  StructureChoice c;
  c.first_sigma_m = MedianAlongSigma(out);
  // The alternative structure, built and on the drive's frames when first needed.
  std::vector<int> alternative_pose_of;
  std::optional<VoStructure> alternative_timed;
  std::optional<structure_internal::DriveAnchoring> other_run;
  const auto alternative_first_pass = [&]() {
    c.alternative_tried = true;
    alternative_timed = on_frames((*alternative)(), &alternative_pose_of);
    other_run.emplace(structure_internal::DriveAnchoring{
        drive, indices, alternative_pose_of, *alternative_timed, load, map_frame, options});
    AnchorDriveResult other = first_pass(*other_run, nullptr);
    c.alternative_sigma_m = MedianAlongSigma(other);
    return other;
  };
  if (alternative && c.first_sigma_m >= options.max_along_sigma_m) {
    // `auto`: the alternative structure too where the first's anchors are not fixed along the
    // road better than the reliability limit. At the limit (the default 0.15 m is half the finest
    // correspondence distance) the median anchor's along-road profile cannot tell a move of one
    // step from its fit: it is placed to the profile's resolution, its Hessian's sigma unused.
    // The first passes decide where their median along-road sigmas differ (the passes
    // then run once); equal medians (the sigma comes in steps of half the finest distance) tell
    // nothing, and the finished runs decide.
    AnchorDriveResult other = alternative_first_pass();
    if (c.alternative_sigma_m == c.first_sigma_m) {
      c.decided_by_finished_runs = true;
      passes(run, &out);
      passes(*other_run, &other);
      c.first_sigma_m = MedianAlongSigma(out);
      c.alternative_sigma_m = MedianAlongSigma(other);
      c.alternative_kept = c.alternative_sigma_m < c.first_sigma_m;
    } else {
      c.alternative_kept = c.alternative_sigma_m < c.first_sigma_m;
      passes(c.alternative_kept ? *other_run : run, c.alternative_kept ? &other : &out);
    }
    if (c.alternative_kept) out = std::move(other);
  } else {
    passes(run, &out);
    c.first_ok = CountOk(out);
    if (alternative &&
        c.first_ok < options.auto_min_ok_share * static_cast<double>(indices.size())) {
      // The first structure fixed the anchors in its first pass but too few are ok in the end:
      // the alternative's finished run too, the one with more ok anchors kept.
      c.decided_by_ok = true;
      AnchorDriveResult other = alternative_first_pass();
      passes(*other_run, &other);
      c.alternative_ok = CountOk(other);
      c.alternative_kept = c.alternative_ok > c.first_ok;
      if (c.alternative_kept) out = std::move(other);
    }
  }
  if (choice) *choice = c;
  out.num_ok = CountOk(out);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace

AnchorDriveResult AnchorDriveByStructure(const AnchorInputs& inputs,
                                         const VoStructure& vo,
                                         const StructureAnchorOptions& options,
                                         const ProgressCallback& progress) {
  return AnchorByStructure(inputs, vo, nullptr, options, progress, nullptr);
}

AnchorDriveResult AnchorDriveByStructureAuto(const AnchorInputs& inputs,
                                             const VoStructure& vo,
                                             const std::function<VoStructure()>& alternative,
                                             const StructureAnchorOptions& options,
                                             const ProgressCallback& progress,
                                             StructureChoice* choice) {
  return AnchorByStructure(inputs, vo, &alternative, options, progress, choice);
}

}  // namespace epiloc
