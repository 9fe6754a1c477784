// The map bundle (StructureAnchorOptions::map_bundle): the posed anchors' windows adjusted, a
// chunk of anchors at a time, to the images and the map at once. See RefineByMapBundle in
// structure_anchor_internal.h.
#include <chrono>
#include <cmath>
#include <unordered_map>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "epiloc/io/frame_reader.h"
#include "structure_anchor_internal.h"

namespace epiloc {
namespace structure_internal {
namespace {

// Reprojection error in pixels of a point seen at normalised coordinates `x`; the pose is
// cam_from_map as angle-axis (3) and translation (3).
struct SightingCost {
  SightingCost(const Eigen::Vector2d& x, double focal_px) : x_(x), focal_px_(focal_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    T p[3];
    ceres::AngleAxisRotatePoint(pose, point, p);
    for (int i = 0; i < 3; ++i) p[i] += pose[3 + i];
    const T z = p[2] > T(1e-3) ? p[2] : T(1e-3);  // behind the camera: the loss caps it
    residual[0] = T(focal_px_) * (p[0] / z - T(x_.x()));
    residual[1] = T(focal_px_) * (p[1] / z - T(x_.y()));
    return true;
  }

  Eigen::Vector2d x_;
  double focal_px_;
};

// A point's distance from the map's local plane (normal n through q) in units of sigma.
struct PlaneCost {
  PlaneCost(const Eigen::Vector3d& n, const Eigen::Vector3d& q, double sigma_m)
      : n_(n), q_(q), sigma_m_(sigma_m) {}

  template <typename T>
  bool operator()(const T* point, T* residual) const {
    residual[0] = (T(n_.x()) * (point[0] - T(q_.x())) + T(n_.y()) * (point[1] - T(q_.y())) +
                   T(n_.z()) * (point[2] - T(q_.z()))) /
                  T(sigma_m_);
    return true;
  }

  Eigen::Vector3d n_, q_;
  double sigma_m_;
};

// The camera's centre (-R^T t) held at `centre` within sigma: the bundle's gauge along the road,
// where a street's surfaces leave it free.
struct CentreCost {
  CentreCost(const Eigen::Vector3d& centre, double sigma_m) : centre_(centre), sigma_m_(sigma_m) {}

  template <typename T>
  bool operator()(const T* pose, T* residual) const {
    const T inverse[3] = {-pose[0], -pose[1], -pose[2]};
    T c[3];
    ceres::AngleAxisRotatePoint(inverse, pose + 3, c);
    for (int i = 0; i < 3; ++i) residual[i] = (-c[i] - T(centre_[i])) / T(sigma_m_);
    return true;
  }

  Eigen::Vector3d centre_;
  double sigma_m_;
};

// The camera's roll against the one its image's vertical lines show: the map's z turned into
// the camera's axes, its component along the measurement's tangent about the optical axis
// (t_x . u: zero where the camera's up is the measured one), over its standard error. The pitch
// those lines show is left out: in a camera that looks along the road vertical lines are nearly
// parallel, so their convergence (the pitch) is a second-order effect that a leaning tree or a
// lens model's error outweighs (KITTI: 0.3-0.8 deg off; README).
struct RollCost {
  RollCost(const Eigen::Vector3d& tangent_x, double sigma_rad) : t_(tangent_x), sigma_(sigma_rad) {}

  template <typename T>
  bool operator()(const T* pose, T* residual) const {
    const T z[3] = {T(0), T(0), T(1)};
    T u[3];
    ceres::AngleAxisRotatePoint(pose, z, u);
    residual[0] = (T(t_.x()) * u[0] + T(t_.y()) * u[1] + T(t_.z()) * u[2]) / T(sigma_);
    return true;
  }

  Eigen::Vector3d t_;
  double sigma_;
};

using Pose6 = std::array<double, 6>;

Pose6 ToPose6(const Eigen::Quaterniond& map_from_cam, const Eigen::Vector3d& centre) {
  const Eigen::Matrix3d r = map_from_cam.toRotationMatrix().transpose();
  const Eigen::AngleAxisd aa(r);
  const Eigen::Vector3d v = aa.angle() * aa.axis();
  const Eigen::Vector3d t = -r * centre;
  return {v.x(), v.y(), v.z(), t.x(), t.y(), t.z()};
}

Eigen::Quaterniond MapFromCam(const Pose6& pose) {
  const Eigen::Vector3d v(pose[0], pose[1], pose[2]);
  const double angle = v.norm();
  const Eigen::Quaterniond cam_from_map =
      angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle))
                  : Eigen::Quaterniond::Identity();
  return cam_from_map.conjugate().normalized();
}

// The unit normal of a plane's projector n n^T; none for a line's or a point's.
std::optional<Eigen::Vector3d> PlaneNormal(const Eigen::Matrix3f& projector) {
  if (std::abs(projector.trace() - 1.0f) > 1e-3f) return std::nullopt;
  int column = 0;
  projector.diagonal().maxCoeff(&column);
  const Eigen::Vector3d n = projector.col(column).cast<double>();
  if (n.norm() <= 1e-6) return std::nullopt;
  return n.normalized();
}

}  // namespace

std::vector<MapBundleResult> AdjustWindowsToMap(const DriveAnchoring& run,
                                                const std::vector<size_t>& ks,
                                                const std::vector<AnchorResult>& anchors) {
  const VoStructure& vo = run.vo;
  const StructureAnchorOptions& options = run.options;
  std::vector<MapBundleResult> results(ks.size());
  if (vo.observation_focal_px <= 0.0 || ks.empty()) return results;
  // The anchors: their VO poses, implied similarities and centres; one segment.
  struct Anchored {
    size_t result;  // index into `results`
    int pose;
    Similarity3 sim;
    Eigen::Vector3d centre;
  };
  std::vector<Anchored> anchored;
  int segment = -2;
  for (size_t i = 0; i < ks.size(); ++i) {
    const int pose = run.pose_of[run.indices[ks[i]]];
    const AnchorResult& a = anchors[i];
    // Only an anchor called ok places the cameras and points around it and holds the gauge: a
    // rejected one is rejected because its place is doubted (metres off on a street that repeats
    // itself), and its similarity would bend the window between its neighbours (below: it takes
    // its camera's rotation only).
    if (pose < 0 || !a.has_pose || a.status != AnchorStatus::kOk) continue;
    const StampedPose& p = vo.poses[static_cast<size_t>(pose)];
    const int s = vo.SegmentOf(p.frame);
    if (segment == -2) segment = s;
    if (s != segment) continue;
    anchored.push_back(
        {i, pose, ImpliedSimilarity(a, p.world_from_cam), a.map_from_cam.translation});
  }
  if (anchored.empty()) return results;
  // Each camera and point is placed by the similarity of the anchor nearest to it in the VO.
  const auto nearest_sim = [&](const Eigen::Vector3d& in_world) -> const Similarity3& {
    size_t best = 0;
    double best_d = INFINITY;
    for (size_t i = 0; i < anchored.size(); ++i) {
      const double d =
          (vo.poses[static_cast<size_t>(anchored[i].pose)].world_from_cam.translation - in_world)
              .squaredNorm();
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    return anchored[best].sim;
  };
  const auto near_an_anchor = [&](const Eigen::Vector3d& x, double radius) {
    for (const Anchored& a : anchored) {
      if ((x - a.centre).norm() <= radius) return true;
    }
    return false;
  };

  // The window: the segment's poses within bundle_window_m / 2 of an anchor's camera.
  const double half = 0.5 * options.bundle_window_m;
  std::unordered_map<frame_t, int> camera_of;  // drive frame -> index in `cameras`
  std::vector<Pose6> cameras;
  std::vector<frame_t> camera_frames;  // the drive frame of each camera
  for (size_t j = 0; j < vo.poses.size(); ++j) {
    const StampedPose& p = vo.poses[j];
    if (p.frame == kInvalidFrame || vo.SegmentOf(p.frame) != segment) continue;
    const Similarity3& sim = nearest_sim(p.world_from_cam.translation);
    const Eigen::Vector3d centre = sim * p.world_from_cam.translation;
    if (!near_an_anchor(centre, half)) continue;
    camera_of[p.frame] = static_cast<int>(cameras.size());
    camera_frames.push_back(p.frame);
    cameras.push_back(ToPose6(sim.rotation * p.world_from_cam.rotation, centre));
  }
  if (cameras.size() < 3) return results;
  const auto anchor_camera = [&](const Anchored& a) -> Pose6& {
    return cameras[static_cast<size_t>(camera_of.at(vo.poses[static_cast<size_t>(a.pose)].frame))];
  };

  // The points the window's cameras saw twice or more, near an anchor's camera.
  struct Sighting {
    int camera;
    Eigen::Vector2d x;
  };
  std::vector<Eigen::Vector3d> points;
  std::vector<std::vector<Sighting>> sightings;
  for (const VoPoint& p : vo.points) {
    if (p.segment != segment || p.seen.size() < 2) continue;
    const Eigen::Vector3d x = nearest_sim(p.point_in_world) * p.point_in_world;
    if (!near_an_anchor(x, half + options.max_point_range_m)) continue;
    std::vector<Sighting> in_window;
    for (const VoObservation& o : p.seen) {
      const auto it = camera_of.find(o.frame);
      if (it != camera_of.end()) in_window.push_back({it->second, o.normalized});
    }
    if (in_window.size() < 2) continue;
    points.push_back(x);
    sightings.push_back(std::move(in_window));
  }
  if (static_cast<int>(points.size()) < options.registration.min_points) return results;

  // The map around the anchors.
  Eigen::Vector3d lo = anchored.front().centre, hi = lo;
  for (const Anchored& a : anchored) {
    lo = lo.cwiseMin(a.centre);
    hi = hi.cwiseMax(a.centre);
  }
  const PointCloud cloud =
      run.load(0.5 * (lo + hi), 0.5 * (hi - lo).head<2>().norm() + half +
                                    options.max_point_range_m + options.map_margin_m);
  if (cloud.size() < 100) return results;
  StructureMap map(cloud, options.registration);

  // The roll each window camera's image shows (bundle_vertical_lines).
  std::vector<std::optional<RollCost>> rolls(cameras.size());
  if (options.bundle_vertical_lines) {
    std::unordered_map<frame_t, size_t> index_of;
    for (size_t i = 0; i < run.drive.frames.size(); ++i) index_of[run.drive.frames[i].frame] = i;
    std::optional<FrameReader> reader;
    if (!index_of.empty()) reader.emplace(run.drive);
    ParallelFor(static_cast<int64_t>(cameras.size()), options.num_threads, [&](int64_t c) {
      const auto it = index_of.find(camera_frames[static_cast<size_t>(c)]);
      if (it == index_of.end()) return;
      const std::optional<VerticalDirection> m =
          MeasureVertical(reader->ReadGrey(it->second), run.drive.camera, options.vertical_lines);
      if (!m || !(m->covariance(0, 0) > 0.0)) return;
      rolls[static_cast<size_t>(c)].emplace(m->tangent_x, std::sqrt(m->covariance(0, 0)));
    });
    int measured = 0;
    for (const auto& r : rolls) measured += r ? 1 : 0;
    spdlog::debug("map bundle: the vertical from line segments in {} of {} cameras", measured,
                  cameras.size());
  }

  const double focal_px = vo.observation_focal_px;
  int on_planes = 0;
  int iterations = 0;
  for (const double distance_m : options.bundle_distances_m) {
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    ceres::HuberLoss pixel_loss(options.bundle_huber_px);
    ceres::HuberLoss plane_loss(1.0);
    on_planes = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      for (const Sighting& s : sightings[i]) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<SightingCost, 2, 6, 3>(new SightingCost(s.x, focal_px)),
            &pixel_loss, cameras[static_cast<size_t>(s.camera)].data(), points[i].data());
      }
      const int nearest = map.Nearest(points[i], distance_m);
      if (nearest < 0) continue;
      const auto n = PlaneNormal(map.Projector(nearest));
      if (!n) continue;
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<PlaneCost, 1, 3>(
              new PlaneCost(*n, map.Point(nearest).cast<double>(), options.bundle_plane_sigma_m)),
          &plane_loss, points[i].data());
      ++on_planes;
    }
    if (on_planes < options.registration.min_points) return results;
    for (const Anchored& a : anchored) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CentreCost, 3, 6>(
                                   new CentreCost(a.centre, options.bundle_centre_sigma_m)),
                               nullptr, anchor_camera(a).data());
    }
    for (size_t c = 0; c < cameras.size(); ++c) {
      if (!rolls[c]) continue;
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<RollCost, 1, 6>(new RollCost(*rolls[c])), nullptr,
          cameras[c].data());
    }
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::SPARSE_SCHUR;
    solver.max_num_iterations = options.bundle_iterations;
    solver.num_threads = options.num_threads;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    if (!summary.IsSolutionUsable()) return results;
    iterations += static_cast<int>(summary.iterations.size());
  }
  const auto adjusted = [&](const Pose6& camera) {
    MapBundleResult r;
    r.success = true;
    r.map_from_cam = MapFromCam(camera);
    r.centre = -(r.map_from_cam * Eigen::Vector3d(camera[3], camera[4], camera[5]));
    r.cameras = static_cast<int>(cameras.size());
    r.points = static_cast<int>(points.size());
    r.points_on_map = on_planes;
    r.iterations = iterations;
    return r;
  };
  // An anchor not called ok takes the rotation of its frame's camera where the window holds it
  // (the camera placed by the ok anchors around it, as its orientation was by their consensus);
  // its centre, doubted, is its own and stays.
  for (size_t i = 0; i < ks.size(); ++i) {
    const int pose = run.pose_of[run.indices[ks[i]]];
    const AnchorResult& a = anchors[i];
    if (pose < 0 || !a.has_pose || a.status == AnchorStatus::kOk) continue;
    const auto it = camera_of.find(vo.poses[static_cast<size_t>(pose)].frame);
    if (it == camera_of.end()) continue;
    results[i] = adjusted(cameras[static_cast<size_t>(it->second)]);
  }
  for (const Anchored& a : anchored) results[a.result] = adjusted(anchor_camera(a));
  return results;
}

void CheckMapBundleOptions(const StructureAnchorOptions& o) {
  EPILOC_CHECK(std::isfinite(o.bundle_window_m) && o.bundle_window_m > 0,
               "structure anchor: bundle_window_m must be > 0");
  EPILOC_CHECK(o.bundle_iterations >= 1, "structure anchor: bundle_iterations must be >= 1");
  EPILOC_CHECK(std::isfinite(o.bundle_chunk_m) && o.bundle_chunk_m >= 0,
               "structure anchor: bundle_chunk_m must be >= 0");
  EPILOC_CHECK(!o.bundle_distances_m.empty(), "structure anchor: bundle_distances_m is empty");
  for (const double d : o.bundle_distances_m) {
    EPILOC_CHECK(std::isfinite(d) && d > 0, "structure anchor: bundle_distances_m must be > 0");
  }
  EPILOC_CHECK(std::isfinite(o.bundle_plane_sigma_m) && o.bundle_plane_sigma_m > 0,
               "structure anchor: bundle_plane_sigma_m must be > 0");
  EPILOC_CHECK(std::isfinite(o.bundle_huber_px) && o.bundle_huber_px > 0,
               "structure anchor: bundle_huber_px must be > 0");
  EPILOC_CHECK(std::isfinite(o.bundle_centre_sigma_m) && o.bundle_centre_sigma_m > 0,
               "structure anchor: bundle_centre_sigma_m must be > 0");
  o.vertical_lines.Check();
}

MapBundleResult AdjustWindowToMap(const DriveAnchoring& run, size_t k, const AnchorResult& a) {
  return AdjustWindowsToMap(run, {k}, {a}).front();
}

void RefineByMapBundle(const DriveAnchoring& run, AnchorDriveResult* out) {
  // The posed anchors in chunks: consecutive ones of one segment within bundle_chunk_m of the
  // chunk's first.
  std::vector<std::vector<size_t>> chunks;
  int chunk_segment = -2;
  Eigen::Vector3d chunk_start = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < out->frames.size(); ++k) {
    const AnchorResult& a = out->frames[k];
    const int pose = run.pose_of[run.indices[k]];
    if (!a.has_pose || pose < 0) continue;
    const int segment = run.vo.SegmentOf(run.vo.poses[static_cast<size_t>(pose)].frame);
    if (chunks.empty() || segment != chunk_segment ||
        (a.map_from_cam.translation - chunk_start).norm() > run.options.bundle_chunk_m) {
      chunks.emplace_back();
      chunk_segment = segment;
      chunk_start = a.map_from_cam.translation;
    }
    chunks.back().push_back(k);
  }
  for (const std::vector<size_t>& chunk : chunks) {
    const auto start = std::chrono::steady_clock::now();
    std::vector<AnchorResult> anchors;
    for (const size_t k : chunk) anchors.push_back(out->frames[k]);
    const std::vector<MapBundleResult> results = AdjustWindowsToMap(run, chunk, anchors);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    for (size_t i = 0; i < chunk.size(); ++i) {
      AnchorResult& a = out->frames[chunk[i]];
      a.seconds += seconds / static_cast<double>(chunk.size());
      const MapBundleResult& b = results[i];
      if (!b.success) continue;
      spdlog::debug(
          "map bundle frame {}: {} cameras, {} points ({} on the map), turned {:.3f} deg, moved "
          "{:.3f} m",
          a.frame, b.cameras, b.points, b.points_on_map,
          a.map_from_cam.rotation.angularDistance(b.map_from_cam) / kDegToRad,
          (b.centre - a.map_from_cam.translation).head<2>().norm());
      a.map_from_cam.rotation = b.map_from_cam;
      SetCentre(run.map_frame, a.map_from_cam.translation, &a);
      // An ok anchor's camera goes where the images and the map put it, horizontally (its height
      // stays the registration's, as in PlaceByConsensus); a doubted one keeps its own.
      if (a.status == AnchorStatus::kOk)
        a.bundle_move_m = MoveHorizontally(run, b.centre.head<2>(), &a);
    }
  }
}

}  // namespace structure_internal
}  // namespace epiloc
