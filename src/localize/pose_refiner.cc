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
  out.sigma_horizontal_m = std::sqrt(
      std::max({0.0, model(0, 0) + model(1, 1), jack(0, 0) + jack(1, 1)}));
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

PoseRefinement RefineByProjection(
    const Camera& camera,
    const FeatureKeypoints& keypoints,
    const std::vector<float>& query_root_sift,
    const std::vector<std::shared_ptr<const FrameMapPoints>>& local_map,
    const PoseRefinement& initial,
    double s_epipolar_m,
    const Route& route,
    const RefineOptions& options) {
  if (initial.status != RefineStatus::kOk) return initial;
  const int num_query = static_cast<int>(keypoints.rows());
  EPILOC_CHECK(query_root_sift.size() >= static_cast<size_t>(num_query) * 128,
               "RefineByProjection: {} RootSIFT values for {} keypoints", query_root_sift.size(),
               num_query);
  // Query keypoints in a grid of cells the size of the search radius.
  const double radius = options.search_radius_px;
  const int cell = std::max(1, static_cast<int>(std::ceil(radius)));
  const int grid_w = camera.width / cell + 1, grid_h = camera.height / cell + 1;
  std::vector<std::vector<int>> grid(static_cast<size_t>(grid_w) * grid_h);
  const auto cell_of = [&](double x, double y) {
    return std::pair<int, int>(std::clamp(static_cast<int>(x / cell), 0, grid_w - 1),
                               std::clamp(static_cast<int>(y / cell), 0, grid_h - 1));
  };
  for (int q = 0; q < num_query; ++q) {
    const auto [cx, cy] = cell_of(keypoints(q, 0), keypoints(q, 1));
    grid[static_cast<size_t>(cy) * grid_w + cx].push_back(q);
  }
  const auto distance = [&](int q, const float* d) {
    const float* a = query_root_sift.data() + static_cast<size_t>(q) * 128;
    float sum = 0.f;
    for (int k = 0; k < 128; ++k) sum += (a[k] - d[k]) * (a[k] - d[k]);
    return std::sqrt(sum);
  };
  // Per query feature, the best point claiming it.
  struct Claim {
    double distance = INFINITY;
    int64_t point_id = -1;
    Eigen::Vector3d point;
  };
  std::vector<Claim> claims(num_query);
  std::unordered_map<int64_t, bool> seen;
  const Rigid3d cam_from_enu = initial.enu_from_cam.Inverse();
  const Eigen::Matrix3d rotation = cam_from_enu.rotation.toRotationMatrix();
  const double r2 = radius * radius;
  // A projection's variance along its major axis under the initial pose's covariance.
  const auto projection_variance = [&](const Eigen::Vector3d& x) {
    const Eigen::Matrix<double, 2, 6> j = ProjectionPoseJacobian(camera, x, rotation);
    const Eigen::Matrix2d c = j * initial.pose_covariance * j.transpose();
    return 0.5 * (c.trace() + std::hypot(c(0, 0) - c(1, 1), 2.0 * c(0, 1)));
  };
  const double max_variance = (radius / std::max(options.search_sigmas, 1e-9)) *
                              (radius / std::max(options.search_sigmas, 1e-9));
  int num_projected = 0, num_predicted = 0;
  for (const auto& frame : local_map) {
    if (!frame) continue;
    for (int k = 0; k < frame->size(); ++k) {
      const int64_t id = frame->point_id[k];
      if (!seen.emplace(id, true).second) continue;  // one descriptor per point (the first)
      const Eigen::Vector3d x = cam_from_enu * frame->point_in_enu[k];
      if (x.z() < 0.5) continue;
      const Eigen::Vector2d uv = camera.Project(x);
      if (uv.x() < -radius || uv.y() < -radius || uv.x() > camera.width - 1 + radius ||
          uv.y() > camera.height - 1 + radius) {
        continue;
      }
      ++num_projected;
      if (projection_variance(x) > max_variance) continue;
      ++num_predicted;
      const float* d = frame->root_sift.data() + static_cast<size_t>(k) * 128;
      const auto [cx, cy] = cell_of(uv.x(), uv.y());
      double best = INFINITY, second = INFINITY;
      int best_q = -1;
      for (int gy = std::max(0, cy - 1); gy <= std::min(grid_h - 1, cy + 1); ++gy) {
        for (int gx = std::max(0, cx - 1); gx <= std::min(grid_w - 1, cx + 1); ++gx) {
          for (const int q : grid[static_cast<size_t>(gy) * grid_w + gx]) {
            const double du = keypoints(q, 0) - uv.x(), dv = keypoints(q, 1) - uv.y();
            if (du * du + dv * dv > r2) continue;
            const double dist = distance(q, d);
            if (dist < best) {
              second = best;
              best = dist;
              best_q = q;
            } else if (dist < second) {
              second = dist;
            }
          }
        }
      }
      if (best_q < 0 || best > options.max_descriptor_distance ||
          best > options.search_ratio * second) {
        continue;
      }
      if (best < claims[best_q].distance) claims[best_q] = {best, id, frame->point_in_enu[k]};
    }
  }
  if (2 * num_predicted < num_projected) return initial;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  for (int q = 0; q < num_query; ++q) {
    if (claims[q].point_id < 0) continue;
    pixels.emplace_back(keypoints(q, 0), keypoints(q, 1));
    points.push_back(claims[q].point);
  }
  PoseRefinement guided = SolveAndCheck(camera, pixels, points, s_epipolar_m, route, options);
  // The search must add support, not replace a good pose by a worse one.
  if (guided.status != RefineStatus::kOk || guided.num_inliers <= initial.num_inliers) {
    return initial;
  }
  return guided;
}

}  // namespace epiloc
