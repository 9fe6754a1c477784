#include "epiloc/vo/bundle_adjustment.h"

#include <chrono>
#include <cmath>

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Reprojection error in pixels of a point seen at normalised coordinates (u, v). Pose parameters:
// angle-axis rotation (3) and translation (3) of cam_from_world.
struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector2d& x, double focal_px) : x_(x), focal_px_(focal_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    T p[3];
    ceres::AngleAxisRotatePoint(pose, point, p);
    p[0] += pose[3];
    p[1] += pose[4];
    p[2] += pose[5];
    // Points behind the camera are outliers the caller removes; keep the residual finite.
    const T z = p[2] > T(1e-6) ? p[2] : T(1e-6);
    residual[0] = T(focal_px_) * (p[0] / z - T(x_.x()));
    residual[1] = T(focal_px_) * (p[1] / z - T(x_.y()));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& x, double focal_px) {
    return new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 6, 3>(
        new ReprojectionCost(x, focal_px));
  }

  Eigen::Vector2d x_;
  double focal_px_;
};

// The same with the point held fixed (motion-only refinement).
struct PoseOnlyCost {
  PoseOnlyCost(const Eigen::Vector3d& point, const Eigen::Vector2d& x, double focal_px)
      : point_(point), cost_(x, focal_px) {}

  template <typename T>
  bool operator()(const T* pose, T* residual) const {
    const T point[3] = {T(point_.x()), T(point_.y()), T(point_.z())};
    return cost_(pose, point, residual);
  }

  Eigen::Vector3d point_;
  ReprojectionCost cost_;
};

struct PoseParameters {
  double values[6];
};

PoseParameters ToParameters(const Rigid3d& pose) {
  PoseParameters p;
  const Eigen::AngleAxisd aa(pose.rotation.normalized());
  const Eigen::Vector3d v = aa.angle() * aa.axis();
  for (int k = 0; k < 3; ++k) {
    p.values[k] = v[k];
    p.values[3 + k] = pose.translation[k];
  }
  return p;
}

Rigid3d FromParameters(const PoseParameters& p) {
  const Eigen::Vector3d v(p.values[0], p.values[1], p.values[2]);
  const double angle = v.norm();
  const Eigen::Quaterniond q = angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle))
                                           : Eigen::Quaterniond::Identity();
  return Rigid3d(q, Eigen::Vector3d(p.values[3], p.values[4], p.values[5]));
}

double SquaredErrorPx(const Rigid3d& cam_from_world,
                      const Eigen::Vector3d& point,
                      const Eigen::Vector2d& x,
                      double focal_px) {
  const Eigen::Vector3d p = cam_from_world * point;
  if (p.z() <= 1e-6) return std::numeric_limits<double>::infinity();
  return focal_px * focal_px * (p.head<2>() / p.z() - x).squaredNorm();
}

ceres::Solver::Options SolverOptions(const BundleOptions& options, bool schur) {
  ceres::Solver::Options solver;
  solver.linear_solver_type = schur ? ceres::SPARSE_SCHUR : ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = options.num_threads;
  solver.minimizer_progress_to_stdout = false;
  solver.logging_type = ceres::SILENT;
  solver.function_tolerance = 1e-5;
  solver.gradient_tolerance = 1e-8;
  solver.parameter_tolerance = 1e-7;
  return solver;
}

}  // namespace

void BundleOptions::Check() const {
  EPILOC_CHECK(focal_px > 0.0, "vo: focal_px must be > 0, got {}", focal_px);
  EPILOC_CHECK(huber_px > 0.0, "vo: huber_px must be > 0, got {}", huber_px);
  EPILOC_CHECK(max_iterations > 0, "vo: BA max_iterations must be > 0, got {}", max_iterations);
  EPILOC_CHECK(num_threads >= 1, "vo: num_threads must be >= 1, got {}", num_threads);
}

BundleSummary SolveBundle(BundleProblem& problem, const BundleOptions& options) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  const size_t num_poses = problem.cam_from_world.size();
  EPILOC_CHECK(problem.pose_fixed.size() == num_poses, "vo: pose_fixed has {} entries for {} poses",
               problem.pose_fixed.size(), num_poses);
  std::vector<PoseParameters> poses(num_poses);
  for (size_t i = 0; i < num_poses; ++i) poses[i] = ToParameters(problem.cam_from_world[i]);

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);
  ceres::HuberLoss loss(options.huber_px);
  double initial_sum = 0.0;
  for (const BundleObservation& o : problem.observations) {
    EPILOC_CHECK(o.pose >= 0 && static_cast<size_t>(o.pose) < num_poses && o.point >= 0 &&
                     static_cast<size_t>(o.point) < problem.points_in_world.size(),
                 "vo: bundle observation of pose {} / point {} out of range", o.pose, o.point);
    initial_sum +=
        std::min(1e6, SquaredErrorPx(problem.cam_from_world[o.pose],
                                     problem.points_in_world[o.point], o.x, options.focal_px));
    ceres_problem.AddResidualBlock(ReprojectionCost::Create(o.x, options.focal_px), &loss,
                                   poses[o.pose].values, problem.points_in_world[o.point].data());
  }
  BundleSummary summary;
  if (problem.observations.empty()) return summary;
  for (size_t i = 0; i < num_poses; ++i) {
    if (problem.pose_fixed[i] && ceres_problem.HasParameterBlock(poses[i].values)) {
      ceres_problem.SetParameterBlockConstant(poses[i].values);
    }
  }
  if (problem.scale_pose >= 0) {
    EPILOC_CHECK(static_cast<size_t>(problem.scale_pose) < num_poses && problem.scale_axis >= 0 &&
                     problem.scale_axis < 3,
                 "vo: scale gauge pose {} axis {} out of range", problem.scale_pose,
                 problem.scale_axis);
    double* pose = poses[static_cast<size_t>(problem.scale_pose)].values;
    if (!problem.pose_fixed[static_cast<size_t>(problem.scale_pose)] &&
        ceres_problem.HasParameterBlock(pose)) {
      ceres_problem.SetManifold(pose, new ceres::SubsetManifold(6, {3 + problem.scale_axis}));
    }
  }
  ceres::Solver::Summary ceres_summary;
  ceres::Solve(SolverOptions(options, true), &ceres_problem, &ceres_summary);
  summary.solved = ceres_summary.IsSolutionUsable();
  summary.iterations = static_cast<int>(ceres_summary.iterations.size());
  for (size_t i = 0; i < num_poses; ++i) {
    if (!problem.pose_fixed[i]) problem.cam_from_world[i] = FromParameters(poses[i]);
  }
  double final_sum = 0.0;
  for (const BundleObservation& o : problem.observations) {
    final_sum +=
        std::min(1e6, SquaredErrorPx(problem.cam_from_world[o.pose],
                                     problem.points_in_world[o.point], o.x, options.focal_px));
  }
  const double n = static_cast<double>(problem.observations.size());
  summary.initial_rms_px = std::sqrt(initial_sum / n);
  summary.final_rms_px = std::sqrt(final_sum / n);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

MotionOnlyResult RefineMotionOnly(const Rigid3d& cam_from_world,
                                  const std::vector<Eigen::Vector3d>& points_in_world,
                                  const std::vector<Eigen::Vector2d>& x,
                                  double max_error_px,
                                  const BundleOptions& options) {
  options.Check();
  EPILOC_CHECK(points_in_world.size() == x.size(), "vo: {} points but {} observations",
               points_in_world.size(), x.size());
  const size_t n = x.size();
  MotionOnlyResult result;
  result.cam_from_world = cam_from_world;
  result.inliers.assign(n, false);
  const double max_error2 = max_error_px * max_error_px;
  std::vector<bool> use(n, true);
  for (int round = 0; round < 2; ++round) {
    PoseParameters pose = ToParameters(result.cam_from_world);
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    ceres::HuberLoss loss(options.huber_px);
    int used = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!use[i]) continue;
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PoseOnlyCost, 2, 6>(
                                   new PoseOnlyCost(points_in_world[i], x[i], options.focal_px)),
                               &loss, pose.values);
      ++used;
    }
    if (used < 3) break;
    ceres::Solver::Summary summary;
    ceres::Solve(SolverOptions(options, false), &problem, &summary);
    if (!summary.IsSolutionUsable()) break;
    result.cam_from_world = FromParameters(pose);
    for (size_t i = 0; i < n; ++i) {
      use[i] = SquaredErrorPx(result.cam_from_world, points_in_world[i], x[i], options.focal_px) <=
               max_error2;
    }
  }
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double e2 =
        SquaredErrorPx(result.cam_from_world, points_in_world[i], x[i], options.focal_px);
    result.inliers[i] = e2 <= max_error2;
    if (result.inliers[i]) {
      ++result.num_inliers;
      sum += e2;
    }
  }
  result.rms_px = result.num_inliers > 0 ? std::sqrt(sum / result.num_inliers) : 0.0;
  return result;
}

}  // namespace epiloc
