#include "epiloc/vo/two_view.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "epiloc/core/error.h"

namespace epiloc {

void TwoViewOptions::Check() const {
  EPILOC_CHECK(focal_px > 0.0, "vo: focal_px must be > 0, got {}", focal_px);
  EPILOC_CHECK(max_error_px > 0.0, "vo: two-view max_error_px must be > 0, got {}", max_error_px);
  EPILOC_CHECK(confidence > 0.0 && confidence < 1.0, "vo: confidence must be in (0, 1), got {}",
               confidence);
  EPILOC_CHECK(max_iterations > 0, "vo: max_iterations must be > 0, got {}", max_iterations);
  EPILOC_CHECK(min_inliers >= 5, "vo: min_inliers must be >= 5, got {}", min_inliers);
  EPILOC_CHECK(min_points >= 1, "vo: min_points must be >= 1, got {}", min_points);
  EPILOC_CHECK(min_parallax_deg >= 0.0 && min_median_parallax_deg >= 0.0,
               "vo: parallax thresholds must be >= 0");
  EPILOC_CHECK(max_reprojection_px > 0.0, "vo: max_reprojection_px must be > 0, got {}",
               max_reprojection_px);
}

std::optional<Eigen::Vector3d> TriangulatePoint(const Rigid3d& cam1_from_world,
                                                const Rigid3d& cam2_from_world,
                                                const Eigen::Vector2d& x1,
                                                const Eigen::Vector2d& x2) {
  const Eigen::Matrix<double, 3, 4> p1 = cam1_from_world.ToMatrix3x4();
  const Eigen::Matrix<double, 3, 4> p2 = cam2_from_world.ToMatrix3x4();
  Eigen::Matrix4d a;
  a.row(0) = x1.x() * p1.row(2) - p1.row(0);
  a.row(1) = x1.y() * p1.row(2) - p1.row(1);
  a.row(2) = x2.x() * p2.row(2) - p2.row(0);
  a.row(3) = x2.y() * p2.row(2) - p2.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  if (std::abs(h.w()) < 1e-12 * h.head<3>().norm()) return std::nullopt;
  const Eigen::Vector3d point = h.head<3>() / h.w();
  if (!point.allFinite()) return std::nullopt;
  return point;
}

double ParallaxDeg(const Rigid3d& cam1_from_world,
                   const Rigid3d& cam2_from_world,
                   const Eigen::Vector3d& point_in_world) {
  const Eigen::Vector3d c1 = -(cam1_from_world.rotation.conjugate() * cam1_from_world.translation);
  const Eigen::Vector3d c2 = -(cam2_from_world.rotation.conjugate() * cam2_from_world.translation);
  const Eigen::Vector3d r1 = (point_in_world - c1).normalized();
  const Eigen::Vector3d r2 = (point_in_world - c2).normalized();
  return std::acos(std::clamp(r1.dot(r2), -1.0, 1.0)) * 180.0 / M_PI;
}

double SquaredReprojectionError(const Rigid3d& cam_from_world,
                                const Eigen::Vector3d& point_in_world,
                                const Eigen::Vector2d& x) {
  const Eigen::Vector3d p = cam_from_world * point_in_world;
  if (p.z() <= 1e-6 * p.norm()) return std::numeric_limits<double>::infinity();
  return (p.head<2>() / p.z() - x).squaredNorm();
}

TwoViewResult EstimateTwoView(const std::vector<Eigen::Vector2d>& x1,
                              const std::vector<Eigen::Vector2d>& x2,
                              const TwoViewOptions& options) {
  options.Check();
  EPILOC_CHECK(x1.size() == x2.size(), "vo: {} points in view 1 but {} in view 2", x1.size(),
               x2.size());
  TwoViewResult result;
  const int n = static_cast<int>(x1.size());
  result.points_in_cam1.assign(x1.size(), std::nullopt);
  if (n < options.min_inliers) {
    result.failure = "too few correspondences";
    return result;
  }
  std::vector<cv::Point2d> p1(n), p2(n);
  for (int i = 0; i < n; ++i) {
    p1[i] = {x1[i].x(), x1[i].y()};
    p2[i] = {x2[i].x(), x2[i].y()};
  }
  cv::UsacParams usac;
  usac.threshold = options.max_error_px / options.focal_px;
  usac.confidence = options.confidence;
  usac.maxIterations = options.max_iterations;
  usac.randomGeneratorState = static_cast<int>(options.seed & 0x7fffffff);
  usac.loMethod = cv::LOCAL_OPTIM_INNER_LO;
  usac.score = cv::SCORE_METHOD_MSAC;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat mask, essential;
  try {
    essential = cv::findEssentialMat(p1, p2, eye, eye, cv::noArray(), cv::noArray(), mask, usac);
  } catch (const cv::Exception& e) {
    result.failure = std::string("essential matrix failed: ") + e.err;
    return result;
  }
  if (essential.rows < 3 || essential.cols != 3 || mask.empty()) {
    result.failure = "no essential matrix";
    return result;
  }
  if (essential.rows > 3) essential = essential.rowRange(0, 3).clone();
  if (mask.type() != CV_8U) mask.convertTo(mask, CV_8U);
  mask = mask.reshape(1, n).clone();
  cv::Mat rotation, translation;
  constexpr double kFarPointDistance = 1e6;  // street scenes reach hundreds of baselines deep
  cv::Mat triangulated;
  const int in_front = cv::recoverPose(essential, p1, p2, eye, rotation, translation,
                                       kFarPointDistance, mask, triangulated);
  result.num_inliers = in_front;
  if (in_front < options.min_inliers) {
    result.failure = "too few inliers in front of both cameras";
    return result;
  }
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, r);
  cv::cv2eigen(translation, t);
  result.cam2_from_cam1 = Rigid3d::FromMatrix(r, t.normalized());

  const Rigid3d cam1_from_cam1;
  const double max_error2 = std::pow(options.max_reprojection_px / options.focal_px, 2);
  std::vector<double> parallax;
  int with_parallax = 0;
  for (int i = 0; i < n; ++i) {
    if (!mask.at<uchar>(i)) continue;
    const auto point = TriangulatePoint(cam1_from_cam1, result.cam2_from_cam1, x1[i], x2[i]);
    if (!point) continue;
    if (SquaredReprojectionError(cam1_from_cam1, *point, x1[i]) > max_error2 ||
        SquaredReprojectionError(result.cam2_from_cam1, *point, x2[i]) > max_error2) {
      continue;
    }
    const double angle = ParallaxDeg(cam1_from_cam1, result.cam2_from_cam1, *point);
    parallax.push_back(angle);
    if (angle >= options.min_parallax_deg) ++with_parallax;
    result.points_in_cam1[i] = *point;
  }
  result.num_triangulated = static_cast<int>(parallax.size());
  if (!parallax.empty()) {
    std::nth_element(parallax.begin(), parallax.begin() + parallax.size() / 2, parallax.end());
    result.median_parallax_deg = parallax[parallax.size() / 2];
  }
  if (with_parallax < options.min_points) {
    result.failure = "too few points with parallax";
    return result;
  }
  if (result.median_parallax_deg < options.min_median_parallax_deg) {
    result.failure = "too little parallax";
    return result;
  }
  result.ok = true;
  return result;
}

}  // namespace epiloc
