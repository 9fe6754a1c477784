#include "epiloc/geometry/absolute_pose.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <utility>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Squared reprojection errors (pixels^2) of every correspondence; infinity behind the camera.
std::vector<double> SquaredErrors(const std::vector<Eigen::Vector2d>& points2d,
                                  const std::vector<Eigen::Vector3d>& points3d,
                                  const Camera& camera,
                                  const Rigid3d& cam_from_world) {
  std::vector<double> errors(points2d.size());
  for (size_t i = 0; i < points2d.size(); ++i) {
    const Eigen::Vector3d x = cam_from_world * points3d[i];
    if (x.z() <= 1e-6) {
      errors[i] = INFINITY;
      continue;
    }
    const Eigen::Vector2d p(camera.fx * x.x() / x.z() + camera.cx,
                            camera.fy * x.y() / x.z() + camera.cy);
    errors[i] = (p - points2d[i]).squaredNorm();
  }
  return errors;
}

Rigid3d FromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  cv::cv2eigen(r, rotation);
  cv::cv2eigen(tvec, translation);
  return Rigid3d::FromMatrix(rotation, translation);
}

void ToRvecTvec(const Rigid3d& pose, cv::Mat* rvec, cv::Mat* tvec) {
  cv::Mat r;
  cv::eigen2cv(Eigen::Matrix3d(pose.rotation.toRotationMatrix()), r);
  cv::Rodrigues(r, *rvec);
  cv::eigen2cv(pose.translation, *tvec);
}

// One inlier's terms of the Gauss-Newton normal equations at the pose found.
struct InlierTerms {
  double column = 0.0;                  // pixel x
  Eigen::Matrix<double, 2, 6> jacobian;  // ProjectionPoseJacobian
  Eigen::Vector2d residual;             // observed minus projected pixel
};

// The grouped jackknife of the camera centre (PnpResult::center_covariance_jackknife): the
// inliers sorted by image column are cut into K bands of equal count; without each band the
// pose moves by one Gauss-Newton step from the optimum (the linearised jackknife: exact to first
// order, and a 6x6 solve per band instead of a refinement). `normal` and `gradient` are the sums
// of J^T J and J^T r over all `terms`.
void Jackknife(std::vector<InlierTerms> terms,
               const Eigen::Matrix<double, 6, 6>& normal,
               const Eigen::Matrix<double, 6, 1>& gradient,
               const PnpOptions& options,
               PnpResult* result) {
  const int n = static_cast<int>(terms.size());
  const int groups = std::min(options.jackknife_groups, n / options.jackknife_min_group);
  if (groups < 3) return;
  std::stable_sort(terms.begin(), terms.end(), [](const InlierTerms& a, const InlierTerms& b) {
    return a.column < b.column;
  });
  std::vector<Eigen::Vector3d> shifts;
  for (int g = 0; g < groups; ++g) {
    Eigen::Matrix<double, 6, 6> h = normal;
    Eigen::Matrix<double, 6, 1> b = gradient;
    for (int j = g * n / groups; j < (g + 1) * n / groups; ++j) {
      h -= terms[j].jacobian.transpose() * terms[j].jacobian;
      b -= terms[j].jacobian.transpose() * terms[j].residual;
    }
    const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(h);
    if (!lu.isInvertible()) {
      // The other bands alone do not fix the pose: it rests on one region of the image.
      result->center_covariance_jackknife = Eigen::Matrix3d::Identity() * 1e6;
      result->jackknife_groups = groups;
      return;
    }
    shifts.push_back(lu.solve(b).tail<3>());
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : shifts) mean += c;
  mean /= groups;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& c : shifts) scatter += (c - mean) * (c - mean).transpose();
  result->center_covariance_jackknife = scatter * (groups - 1.0) / groups;
  result->jackknife_groups = groups;
}

}  // namespace

void PnpOptions::Check() const {
  EPILOC_CHECK(std::isfinite(max_reprojection_px) && max_reprojection_px > 0,
               "pnp options: max_reprojection_px must be > 0, got {}", max_reprojection_px);
  EPILOC_CHECK(confidence > 0 && confidence < 1, "pnp options: confidence must be in (0, 1)");
  EPILOC_CHECK(max_iterations >= 1, "pnp options: max_iterations must be >= 1");
  EPILOC_CHECK(min_inliers >= 4, "pnp options: min_inliers must be >= 4, got {}", min_inliers);
  EPILOC_CHECK(refine_rounds >= 0, "pnp options: refine_rounds must be >= 0");
  EPILOC_CHECK(jackknife_groups >= 0, "pnp options: jackknife_groups must be >= 0");
  EPILOC_CHECK(jackknife_min_group >= 1, "pnp options: jackknife_min_group must be >= 1");
}

Eigen::Matrix<double, 2, 6> ProjectionPoseJacobian(const Camera& camera,
                                                   const Eigen::Vector3d& x,
                                                   const Eigen::Matrix3d& rotation) {
  Eigen::Matrix<double, 2, 3> projection;
  projection << camera.fx / x.z(), 0.0, -camera.fx * x.x() / (x.z() * x.z()), 0.0,
      camera.fy / x.z(), -camera.fy * x.y() / (x.z() * x.z());
  Eigen::Matrix3d skew;
  skew << 0.0, -x.z(), x.y(), x.z(), 0.0, -x.x(), -x.y(), x.x(), 0.0;
  Eigen::Matrix<double, 2, 6> j;
  j.leftCols<3>() = -projection * skew;
  j.rightCols<3>() = -projection * rotation;
  return j;
}

PnpResult EstimateAbsolutePose(const std::vector<Eigen::Vector2d>& points2d,
                               const std::vector<Eigen::Vector3d>& points3d,
                               const Camera& camera,
                               const PnpOptions& options) {
  options.Check();
  EPILOC_CHECK(points2d.size() == points3d.size(), "EstimateAbsolutePose: {} pixels but {} points",
               points2d.size(), points3d.size());
  PnpResult result;
  const int n = static_cast<int>(points2d.size());
  if (n < std::max(options.min_inliers, 6)) {
    result.message = fmt::format("{} correspondences, fewer than the {} needed", n,
                                 std::max(options.min_inliers, 6));
    return result;
  }
  // Solve about the points' centroid: map coordinates can be kilometres from their origin.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points3d) centroid += p;
  centroid /= n;
  std::vector<cv::Point3d> object(n);
  std::vector<cv::Point2d> image(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = points3d[i] - centroid;
    object[i] = cv::Point3d(p.x(), p.y(), p.z());
    image[i] = cv::Point2d(points2d[i].x(), points2d[i].y());
  }
  cv::Mat k;
  cv::eigen2cv(camera.K(), k);
  cv::UsacParams usac;
  usac.score = cv::SCORE_METHOD_MAGSAC;
  usac.loMethod = cv::LOCAL_OPTIM_SIGMA;
  usac.sampler = cv::SAMPLING_UNIFORM;
  usac.threshold = options.max_reprojection_px;
  usac.confidence = options.confidence;
  usac.maxIterations = options.max_iterations;
  usac.randomGeneratorState = 12345;  // deterministic
  cv::Mat rvec, tvec, inliers;
  bool ok = false;
  try {
    ok = cv::solvePnPRansac(object, image, k, cv::noArray(), rvec, tvec, inliers, usac);
  } catch (const cv::Exception& e) {
    result.message = std::string("PnP RANSAC failed: ") + e.what();
    return result;
  }
  if (!ok || rvec.empty()) {
    result.message = fmt::format("PnP RANSAC found no pose ({} correspondences)", n);
    return result;
  }
  // Centred pose -> world pose: x_cam = R (x - c) + t = R x + (t - R c).
  Rigid3d centred = FromRvecTvec(rvec, tvec);
  const double threshold2 = options.max_reprojection_px * options.max_reprojection_px;
  std::vector<Eigen::Vector2d> centred2d = points2d;
  std::vector<Eigen::Vector3d> centred3d(n);
  for (int i = 0; i < n; ++i) centred3d[i] = points3d[i] - centroid;
  std::vector<double> errors = SquaredErrors(centred2d, centred3d, camera, centred);
  for (int round = 0; round < options.refine_rounds; ++round) {
    std::vector<cv::Point3d> in_object;
    std::vector<cv::Point2d> in_image;
    for (int i = 0; i < n; ++i) {
      if (errors[i] > threshold2) continue;
      in_object.push_back(object[i]);
      in_image.push_back(image[i]);
    }
    if (static_cast<int>(in_object.size()) < 6) break;
    ToRvecTvec(centred, &rvec, &tvec);
    cv::solvePnPRefineLM(
        in_object, in_image, k, cv::noArray(), rvec, tvec,
        cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-10));
    centred = FromRvecTvec(rvec, tvec);
    errors = SquaredErrors(centred2d, centred3d, camera, centred);
  }
  result.inlier_mask.assign(n, 0);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    if (errors[i] > threshold2) continue;
    result.inlier_mask[i] = 1;
    ++result.num_inliers;
    sum += errors[i];
  }
  result.cam_from_world =
      Rigid3d(centred.rotation, centred.translation - (centred.rotation * centroid));
  result.rmse_px = result.num_inliers > 0 ? std::sqrt(sum / result.num_inliers) : INFINITY;
  if (result.num_inliers < options.min_inliers) {
    result.message = fmt::format("{} PnP inliers of {} correspondences, fewer than {}",
                                 result.num_inliers, n, options.min_inliers);
    return result;
  }
  // Covariance of the pose from the inliers' Gauss-Newton normal matrix (ProjectionPoseJacobian);
  // the pixel noise is the inliers' own residual scale (RSS over n - 6).
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> gradient = Eigen::Matrix<double, 6, 1>::Zero();
  std::vector<InlierTerms> terms;
  terms.reserve(result.num_inliers);
  const Eigen::Matrix3d r = centred.rotation.toRotationMatrix();
  for (int i = 0; i < n; ++i) {
    if (!result.inlier_mask[i]) continue;
    const Eigen::Vector3d x = r * centred3d[i] + centred.translation;
    if (!(x.z() > 1e-9)) continue;
    InlierTerms t;
    t.column = points2d[i].x();
    t.jacobian = ProjectionPoseJacobian(camera, x, r);
    t.residual = points2d[i] - Eigen::Vector2d(camera.fx * x.x() / x.z() + camera.cx,
                                               camera.fy * x.y() / x.z() + camera.cy);
    normal += t.jacobian.transpose() * t.jacobian;
    gradient += t.jacobian.transpose() * t.residual;
    terms.push_back(t);
  }
  const double dof = std::max(1, result.num_inliers - 6);
  const double sigma2 = sum / dof;
  Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(normal);
  if (lu.isInvertible()) {
    result.pose_covariance = sigma2 * lu.inverse();
  } else {
    result.pose_covariance = Eigen::Matrix<double, 6, 6>::Identity() * 1e6;
  }
  result.center_covariance = result.pose_covariance.bottomRightCorner<3, 3>();
  Jackknife(std::move(terms), normal, gradient, options, &result);
  result.success = true;
  return result;
}

}  // namespace epiloc
