#include "epiloc/localize/pose_refiner.h"

#include <cmath>
#include <unordered_map>

#include "epiloc/core/error.h"

namespace epiloc {

PnpOptions RefineOptions::DefaultPnp() {
  PnpOptions pnp;
  pnp.max_reprojection_px = 2.0;
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

PoseRefinement RefinePose(const Camera& camera,
                          const FeatureKeypoints& keypoints,
                          const std::vector<PairResult>& pairs,
                          double s_epipolar_m,
                          const Route& route,
                          const RefineOptions& options) {
  PoseRefinement out;
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
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const int row : order) {
    const std::vector<Vote>& candidates = votes.at(row);
    const Vote* best = &candidates.front();
    for (const Vote& v : candidates) {
      if (v.count > best->count) best = &v;
    }
    pixels.emplace_back(keypoints(row, 0), keypoints(row, 1));
    points.push_back(best->point);
    centroid += best->point;
  }
  out.num_correspondences = static_cast<int>(points.size());
  if (out.num_correspondences < options.min_correspondences) {
    out.status = RefineStatus::kThin;
    out.message = fmt::format("{} 2D-3D correspondences, fewer than {}", out.num_correspondences,
                              options.min_correspondences);
    return out;
  }
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
    out.message = fmt::format("PnP pose {:+.2f} m along the route from the epipolar estimate", along);
    return out;
  }
  if (std::abs(out.projection.cross_track_m) > options.max_cross_track_m) {
    out.status = RefineStatus::kRejected;
    out.message = fmt::format("PnP pose {:.1f} m off the route", out.projection.cross_track_m);
    return out;
  }
  out.status = RefineStatus::kOk;
  return out;
}

}  // namespace epiloc
