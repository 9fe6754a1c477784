#include "epiloc/localize/pose_refiner.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "epiloc/core/error.h"

namespace epiloc {

PnpOptions RefineOptions::DefaultPnp() {
  PnpOptions pnp;
  // Wide: survey points carry a few pixels of error where the survey poses are least
  // consistent (turns); a strict threshold keeps an arbitrary subset of them and the pose jumps
  // from frame to frame, a wide one averages over all (the sequence checks catch gross poses).
  pnp.max_reprojection_px = 5.0;
  pnp.max_iterations = 2000;
  pnp.min_inliers = 12;
  return pnp;
}

void RefineOptions::Check() const {
  EPILOC_CHECK(min_correspondences >= 4, "refine: min_correspondences must be >= 4, got {}",
               min_correspondences);
  EPILOC_CHECK(min_inliers >= pnp.min_inliers, "refine: min_inliers must be >= {} (PnP), got {}",
               pnp.min_inliers, min_inliers);
  EPILOC_CHECK(std::isfinite(max_along_disagreement_m) && max_along_disagreement_m > 0,
               "refine: max_along_disagreement_m must be > 0");
  EPILOC_CHECK(std::isfinite(max_cross_track_m) && max_cross_track_m > 0,
               "refine: max_cross_track_m must be > 0");
  EPILOC_CHECK(std::isfinite(search_radius_px) && search_radius_px > 0 &&
                   std::isfinite(max_descriptor_distance) && max_descriptor_distance > 0 &&
                   search_ratio > 0 && search_ratio <= 1,
               "refine: invalid search by projection (radius {} px, distance {}, ratio {})",
               search_radius_px, max_descriptor_distance, search_ratio);
  EPILOC_CHECK(std::isfinite(search_sigmas) && search_sigmas >= 0,
               "refine: search_sigmas must be >= 0, got {}", search_sigmas);
  pnp.Check();
}

const char* RefineStatusName(RefineStatus status) {
  switch (status) {
    case RefineStatus::kOk:
      return "ok";
    case RefineStatus::kThin:
      return "thin";
    case RefineStatus::kRejected:
      return "rejected";
  }
  return "?";
}

namespace {

// PnP on the correspondences (world points shifted to their centroid) and the checks against the
// sequence (see the header).
PoseRefinement SolveAndCheck(const Camera& camera,
                             const std::vector<Eigen::Vector2d>& pixels,
                             std::vector<Eigen::Vector3d> points,
                             double s_epipolar_m,
                             const Route& route,
                             const RefineOptions& options) {
  PoseRefinement out;
  out.num_correspondences = static_cast<int>(points.size());
  if (out.num_correspondences < options.min_correspondences) {
    out.status = RefineStatus::kThin;
    out.message = fmt::format("{} 2D-3D correspondences, fewer than {}", out.num_correspondences,
                              options.min_correspondences);
    return out;
  }
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& x : points) centroid += x;
  centroid /= static_cast<double>(points.size());
  for (Eigen::Vector3d& x : points) x -= centroid;
  const PnpResult pnp = EstimateAbsolutePose(pixels, points, camera, options.pnp);
  out.num_inliers = pnp.num_inliers;
  out.rmse_px = pnp.rmse_px;
  if (!pnp.success || pnp.num_inliers < options.min_inliers) {
    out.status = RefineStatus::kThin;
    out.message = pnp.success ? fmt::format("{} PnP inliers, fewer than {}", pnp.num_inliers,
                                            options.min_inliers)
                              : pnp.message;
    return out;
  }
  // cam_from_centred = [R | t] with x_cam = R (x_enu - c) + t.
  const Rigid3d centred_from_cam = pnp.cam_from_world.Inverse();
  out.enu_from_cam = Rigid3d(centred_from_cam.rotation, centred_from_cam.translation + centroid);
  out.projection = route.ProjectNear(out.enu_from_cam.translation, s_epipolar_m,
                                     4.0 * options.max_along_disagreement_m + 10.0);
  const double along = out.projection.s_m - s_epipolar_m;
  if (std::abs(along) > options.max_along_disagreement_m) {
    out.status = RefineStatus::kRejected;
    out.message =
        fmt::format("PnP pose {:+.2f} m along the route from the epipolar estimate", along);
    return out;
  }
  if (std::abs(out.projection.cross_track_m) > options.max_cross_track_m) {
    out.status = RefineStatus::kRejected;
    out.message = fmt::format("PnP pose {:.1f} m off the route", out.projection.cross_track_m);
    return out;
  }
  // Uncertainty of the camera centre along the route and horizontally (ENU x, y).
  Eigen::Vector3d along_axis = route.DirectionAt(out.projection.s_m);
  along_axis.z() = 0.0;
  if (along_axis.norm() > 1e-9) along_axis.normalize();
  // Each the larger of the model's and the jackknife's (errors shared by a region of the image).
  const Eigen::Matrix3d& model = pnp.center_covariance;
  const Eigen::Matrix3d& jack = pnp.center_covariance_jackknife;
  const double along_model = std::max(0.0, along_axis.dot(model * along_axis));
  out.sigma_along_model_m = std::sqrt(along_model);
  out.sigma_along_m = std::sqrt(std::max(along_model, along_axis.dot(jack * along_axis)));
  out.sigma_horizontal_m =
      std::sqrt(std::max({0.0, model(0, 0) + model(1, 1), jack(0, 0) + jack(1, 1)}));
  out.pose_covariance = pnp.pose_covariance;
  out.status = RefineStatus::kOk;
  return out;
}

}  // namespace

PoseRefinement RefinePose(const Camera& camera,
                          const FeatureKeypoints& keypoints,
                          const std::vector<PairResult>& pairs,
                          double s_epipolar_m,
                          const Route& route,
                          const RefineOptions& options) {
  // Votes per query row for the points its matches see.
  struct Vote {
    int64_t point_id;
    Eigen::Vector3d point;
    int count;
  };
  std::unordered_map<int, std::vector<Vote>> votes;
  std::vector<int> order;  // query rows in first-seen order (deterministic output)
  for (const PairResult& pair : pairs) {
    for (const PointMatch& m : pair.point_matches) {
      auto [it, inserted] = votes.try_emplace(m.query_row);
      if (inserted) order.push_back(m.query_row);
      bool found = false;
      for (Vote& v : it->second) {
        if (v.point_id == m.point_id) {
          ++v.count;
          found = true;
          break;
        }
      }
      if (!found) it->second.push_back({m.point_id, m.point_in_enu, 1});
    }
  }
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  for (const int row : order) {
    const std::vector<Vote>& candidates = votes.at(row);
    const Vote* best = &candidates.front();
    for (const Vote& v : candidates) {
      if (v.count > best->count) best = &v;
    }
    pixels.emplace_back(keypoints(row, 0), keypoints(row, 1));
    points.push_back(best->point);
  }
  return SolveAndCheck(camera, pixels, points, s_epipolar_m, route, options);
}

namespace {

// A map point in view of a pose: its projection, the variance of that projection along its major
// axis under the pose's covariance (px^2), and its descriptor.
struct Projected {
  Eigen::Vector3d point_in_enu;
  Eigen::Vector2d uv;
  double variance_px2;
  const float* root_sift;
};

// Query keypoints binned in square cells, for the searches within a radius.
class KeypointGrid {
 public:
  KeypointGrid(const Camera& camera, const FeatureKeypoints& keypoints, int cell_px)
      : keypoints_(keypoints),
        cell_(std::max(1, cell_px)),
        w_(camera.width / cell_ + 1),
        h_(camera.height / cell_ + 1),
        cells_(static_cast<size_t>(w_) * h_) {
    for (int q = 0; q < static_cast<int>(keypoints.rows()); ++q) {
      cells_[static_cast<size_t>(Cell(keypoints(q, 1), h_)) * w_ + Cell(keypoints(q, 0), w_)]
          .push_back(q);
    }
  }
  // Calls f(q) for every keypoint q within `radius_px` of `uv`.
  template <typename F>
  void ForEachWithin(const Eigen::Vector2d& uv, double radius_px, F&& f) const {
    const int cx = Cell(uv.x(), w_), cy = Cell(uv.y(), h_);
    const int reach = static_cast<int>(std::ceil(radius_px / cell_));
    const double r2 = radius_px * radius_px;
    for (int gy = std::max(0, cy - reach); gy <= std::min(h_ - 1, cy + reach); ++gy) {
      for (int gx = std::max(0, cx - reach); gx <= std::min(w_ - 1, cx + reach); ++gx) {
        for (const int q : cells_[static_cast<size_t>(gy) * w_ + gx]) {
          const double du = keypoints_(q, 0) - uv.x(), dv = keypoints_(q, 1) - uv.y();
          if (du * du + dv * dv <= r2) f(q);
        }
      }
    }
  }

 private:
  int Cell(double v, int n) const { return std::clamp(static_cast<int>(v / cell_), 0, n - 1); }
  const FeatureKeypoints& keypoints_;
  int cell_, w_, h_;
  std::vector<std::vector<int>> cells_;
};

// Each point with radius_px(point) > 0 matched to the query feature within that radius of its
// projection with the nearest RootSIFT descriptor (at most max_descriptor_distance, below
// search_ratio times the second nearest within the radius); a feature claimed by several points
// keeps the closest descriptor. Appends the correspondences.
template <typename RadiusFn>
void MatchProjected(const std::vector<Projected>& projected,
                    const FeatureKeypoints& keypoints,
                    const std::vector<float>& query_root_sift,
                    const KeypointGrid& grid,
                    RadiusFn radius_px,
                    const RefineOptions& options,
                    std::vector<Eigen::Vector2d>* pixels,
                    std::vector<Eigen::Vector3d>* points) {
  struct Claim {
    double distance = INFINITY;
    const Projected* point = nullptr;
  };
  std::vector<Claim> claims(keypoints.rows());
  for (const Projected& p : projected) {
    const double radius = radius_px(p);
    if (!(radius > 0)) continue;
    double best = INFINITY, second = INFINITY;
    int best_q = -1;
    grid.ForEachWithin(p.uv, radius, [&](int q) {
      const float* a = query_root_sift.data() + static_cast<size_t>(q) * 128;
      float sum = 0.f;
      for (int k = 0; k < 128; ++k) sum += (a[k] - p.root_sift[k]) * (a[k] - p.root_sift[k]);
      const double dist = std::sqrt(sum);
      if (dist < best) {
        second = best;
        best = dist;
        best_q = q;
      } else if (dist < second) {
        second = dist;
      }
    });
    if (best_q < 0 || best > options.max_descriptor_distance ||
        best > options.search_ratio * second) {
      continue;
    }
    if (best < claims[best_q].distance) claims[best_q] = {best, &p};
  }
  for (int q = 0; q < static_cast<int>(claims.size()); ++q) {
    if (!claims[q].point) continue;
    pixels->emplace_back(keypoints(q, 0), keypoints(q, 1));
    points->push_back(claims[q].point->point_in_enu);
  }
}

PoseRefinement SearchByProjection(
    const Camera& camera,
    const FeatureKeypoints& keypoints,
    const std::vector<float>& query_root_sift,
    const std::vector<std::shared_ptr<const FrameMapPoints>>& local_map,
    const PoseRefinement& initial,
    double s_epipolar_m,
    const Route& route,
    const RefineOptions& options,
    bool wide) {
  if (initial.status != RefineStatus::kOk) return initial;
  const double radius = options.search_radius_px;
  const Rigid3d cam_from_enu = initial.enu_from_cam.Inverse();
  const Eigen::Matrix3d rotation = cam_from_enu.rotation.toRotationMatrix();
  // The points in view (one descriptor per point: the first frame's).
  std::vector<Projected> projected;
  std::unordered_map<int64_t, bool> seen;
  for (const auto& frame : local_map) {
    if (!frame) continue;
    for (int k = 0; k < frame->size(); ++k) {
      if (!seen.emplace(frame->point_id[k], true).second) continue;
      const Eigen::Vector3d x = cam_from_enu * frame->point_in_enu[k];
      if (x.z() < 0.5) continue;
      const Eigen::Vector2d uv = camera.Project(x);
      if (uv.x() < -radius || uv.y() < -radius || uv.x() > camera.width - 1 + radius ||
          uv.y() > camera.height - 1 + radius) {
        continue;
      }
      const Eigen::Matrix<double, 2, 6> j = ProjectionPoseJacobian(camera, x, rotation);
      const Eigen::Matrix2d c = j * initial.pose_covariance * j.transpose();
      projected.push_back({frame->point_in_enu[k], uv,
                           0.5 * (c.trace() + std::hypot(c(0, 0) - c(1, 1), 2.0 * c(0, 1))),
                           frame->root_sift.data() + static_cast<size_t>(k) * 128});
    }
  }
  const double sigmas = std::max(options.search_sigmas, 1e-9);
  const double max_variance = (radius / sigmas) * (radius / sigmas);
  int num_predicted = 0;
  for (const Projected& p : projected) num_predicted += p.variance_px2 <= max_variance;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  if (2 * num_predicted < static_cast<int>(projected.size())) {
    if (!wide) return initial;
    // The wide search. The model covariance assumes independent pixel errors; scaled up to the
    // along-route sigma the pose carries (the jackknife's when larger).
    const double model = initial.sigma_along_model_m * initial.sigma_along_model_m;
    const double scale =
        model > 0 ? std::max(1.0, initial.sigma_along_m * initial.sigma_along_m / model) : 1.0;
    const KeypointGrid grid(camera, keypoints, 2 * static_cast<int>(std::ceil(radius)));
    MatchProjected(
        projected, keypoints, query_root_sift, grid,
        [&](const Projected& p) {
          return std::max(radius, sigmas * std::sqrt(scale * p.variance_px2));
        },
        options, &pixels, &points);
    const PoseRefinement found =
        SolveAndCheck(camera, pixels, points, s_epipolar_m, route, options);
    if (found.status != RefineStatus::kOk || found.num_inliers <= initial.num_inliers) {
      return initial;
    }
    // The search within the radius from the pose the wide search found (never wide again).
    return SearchByProjection(camera, keypoints, query_root_sift, local_map, found, s_epipolar_m,
                              route, options, false);
  }
  const KeypointGrid grid(camera, keypoints, static_cast<int>(std::ceil(radius)));
  MatchProjected(
      projected, keypoints, query_root_sift, grid,
      [&](const Projected& p) { return p.variance_px2 <= max_variance ? radius : 0.0; }, options,
      &pixels, &points);
  PoseRefinement guided = SolveAndCheck(camera, pixels, points, s_epipolar_m, route, options);
  // The search must add support, not replace a good pose by a worse one.
  if (guided.status != RefineStatus::kOk || guided.num_inliers <= initial.num_inliers) {
    return initial;
  }
  return guided;
}

}  // namespace

PoseRefinement RefineByProjection(
    const Camera& camera,
    const FeatureKeypoints& keypoints,
    const std::vector<float>& query_root_sift,
    const std::vector<std::shared_ptr<const FrameMapPoints>>& local_map,
    const PoseRefinement& initial,
    double s_epipolar_m,
    const Route& route,
    const RefineOptions& options) {
  const int num_query = static_cast<int>(keypoints.rows());
  EPILOC_CHECK(query_root_sift.size() >= static_cast<size_t>(num_query) * 128,
               "RefineByProjection: {} RootSIFT values for {} keypoints", query_root_sift.size(),
               num_query);
  return SearchByProjection(camera, keypoints, query_root_sift, local_map, initial, s_epipolar_m,
                            route, options, options.wide_search);
}

}  // namespace epiloc
