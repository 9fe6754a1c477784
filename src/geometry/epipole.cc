#include "epiloc/geometry/epipole.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "epiloc/core/error.h"
#include "epiloc/core/statistics.h"

namespace epiloc {
namespace {

// Draws OpenCV 4.6 allows findEssentialMat(method = USAC_*), whatever limit it is given.
constexpr int kUsacEssentialDraws = 1000;

cv::Mat ToCv(const Eigen::Matrix3d& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}

// Sampson distance (squared, in the units of the points) of x2^T F x1 = 0.
double SampsonSquared(const Eigen::Matrix3d& f, const cv::Point2d& p1, const cv::Point2d& p2) {
  const Eigen::Vector3d x1(p1.x, p1.y, 1.0), x2(p2.x, p2.y, 1.0);
  const Eigen::Vector3d f_x1 = f * x1;
  const Eigen::Vector3d ft_x2 = f.transpose() * x2;
  const double numerator = x2.dot(f_x1);
  const double denominator = f_x1.head<2>().squaredNorm() + ft_x2.head<2>().squaredNorm();
  return denominator > 0 ? numerator * numerator / denominator
                         : std::numeric_limits<double>::infinity();
}

// Least-squares polish of a RANSAC model: the normalised 8-point solution over all inliers,
// inliers re-selected by Sampson distance, a few rounds (minimal-sample models are noisy; with
// hundreds of inliers the least-squares model is several times more accurate). Points are
// normalised coordinates for an essential matrix (its two equal singular values are enforced)
// or pixels for a fundamental matrix. Returns false if the inliers cannot support a model.
bool PolishOnInliers(const std::vector<cv::Point2d>& p1,
                     const std::vector<cv::Point2d>& p2,
                     double threshold,
                     bool essential,
                     Eigen::Matrix3d& model,
                     cv::Mat& mask) {
  const double threshold2 = threshold * threshold;
  for (int round = 0; round < 3; ++round) {
    std::vector<cv::Point2d> in1, in2;
    for (size_t i = 0; i < p1.size(); ++i) {
      if (mask.at<uchar>(static_cast<int>(i))) {
        in1.push_back(p1[i]);
        in2.push_back(p2[i]);
      }
    }
    if (in1.size() < 8) return false;
    const cv::Mat f = cv::findFundamentalMat(in1, in2, cv::FM_8POINT);
    if (f.rows != 3 || f.cols != 3) return false;
    cv::cv2eigen(f, model);
    if (essential) {
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(model, Eigen::ComputeFullU | Eigen::ComputeFullV);
      const double sigma = 0.5 * (svd.singularValues()(0) + svd.singularValues()(1));
      model = svd.matrixU() * Eigen::Vector3d(sigma, sigma, 0.0).asDiagonal() *
              svd.matrixV().transpose();
    }
    for (size_t i = 0; i < p1.size(); ++i) {
      mask.at<uchar>(static_cast<int>(i)) = SampsonSquared(model, p1[i], p2[i]) < threshold2;
    }
  }
  return true;
}

}  // namespace

void EpipoleOptions::Check() const {
  EPILOC_CHECK(max_error_px > 0, "epipole: max_error_px must be > 0, got {}", max_error_px);
  EPILOC_CHECK(confidence > 0 && confidence < 1, "epipole: confidence must be in (0, 1), got {}",
               confidence);
  EPILOC_CHECK(max_iterations > 0, "epipole: max_iterations must be > 0");
  EPILOC_CHECK(min_inliers >= 8, "epipole: min_inliers must be >= 8, got {}", min_inliers);
  EPILOC_CHECK(min_inlier_ratio >= 0 && min_inlier_ratio <= 1,
               "epipole: min_inlier_ratio must be in [0, 1], got {}", min_inlier_ratio);
  EPILOC_CHECK(min_parallax_deg >= 0, "epipole: min_parallax_deg must be >= 0");
}

double EpipolarDistance(const Eigen::Vector3d& q, double focal_px) {
  if (q.x() == 0.0) return std::numeric_limits<double>::infinity();
  return std::abs(q.z()) / (focal_px * std::abs(q.x()));
}

int RansacIterationCap(const EpipoleOptions& options, int num_matches) {
  options.Check();
  if (num_matches < options.min_inliers) return options.max_iterations;
  // A pair is accepted only with at least this share of inliers, so RANSAC need not search
  // longer than it takes to draw one all-inlier sample at that share with the wanted
  // confidence: a hopeless pair (few matches, none consistent) stops there instead of at the
  // limit. 5 points per sample for the essential matrix, 7 for the fundamental matrix.
  const double share = std::max(options.min_inlier_ratio,
                                static_cast<double>(options.min_inliers) / num_matches);
  const int sample = options.model == EpipoleOptions::Model::kEssential ? 5 : 7;
  const double p_good = std::pow(std::min(1.0, share), sample);
  if (p_good >= 1.0) return 1;
  const double needed = std::ceil(std::log(1.0 - options.confidence) / std::log1p(-p_good));
  return static_cast<int>(std::clamp(needed, 1.0, static_cast<double>(options.max_iterations)));
}

EpipoleResult EstimateEpipole(const std::vector<Eigen::Vector2d>& query_pixels,
                              const Camera& query_camera,
                              const std::vector<Eigen::Vector2d>& db_pixels,
                              const Camera& db_camera,
                              const EpipoleOptions& options) {
  EPILOC_CHECK(query_pixels.size() == db_pixels.size(),
               "epipole: {} query points but {} database points", query_pixels.size(),
               db_pixels.size());
  EpipoleResult result;
  const int n = static_cast<int>(query_pixels.size());
  result.num_matches = n;
  result.inlier_mask.assign(n, 0);
  if (n < options.min_inliers) {
    result.failure = "too few matches";
    return result;
  }

  std::vector<cv::Point2d> query_norm(n), db_norm(n), query_px(n), db_px(n);
  for (int i = 0; i < n; ++i) {
    query_px[i] = {query_pixels[i].x(), query_pixels[i].y()};
    db_px[i] = {db_pixels[i].x(), db_pixels[i].y()};
    query_norm[i] = {(query_px[i].x - query_camera.cx) / query_camera.fx,
                     (query_px[i].y - query_camera.cy) / query_camera.fy};
    db_norm[i] = {(db_px[i].x - db_camera.cx) / db_camera.fx,
                  (db_px[i].y - db_camera.cy) / db_camera.fy};
  }

  const int usac_method =
      options.robust == EpipoleOptions::Robust::kFast ? cv::USAC_FAST : cv::USAC_MAGSAC;
  const int max_iterations = RansacIterationCap(options, n);
  cv::Mat mask;
  cv::Mat essential;
  double fundamental_e_x = std::numeric_limits<double>::quiet_NaN();
  try {
    if (options.model == EpipoleOptions::Model::kEssential) {
      const cv::Mat identity = cv::Mat::eye(3, 3, CV_64F);
      const double threshold = options.max_error_px / query_camera.fx;
      if (options.robust == EpipoleOptions::Robust::kFast && max_iterations < kUsacEssentialDraws) {
        // OpenCV 4.6's findEssentialMat(method = USAC_*) ignores its iteration limit and always
        // allows 1000 draws (usac::findEssentialMat); a hopeless pair spends them all, ~30 ms.
        // Its explicit-parameter form honours the limit: USAC_FAST's settings, fewer draws.
        cv::UsacParams params;
        params.confidence = options.confidence;
        params.threshold = threshold;
        params.maxIterations = max_iterations;
        params.sampler = cv::SAMPLING_UNIFORM;
        params.score = cv::SCORE_METHOD_MSAC;
        params.loMethod = cv::LOCAL_OPTIM_INNER_AND_ITER_LO;
        params.loIterations = 5;
        params.loSampleSize = 16;
        params.isParallel = false;
        params.randomGeneratorState = 0;
        essential = cv::findEssentialMat(query_norm, db_norm, identity, identity, cv::noArray(),
                                         cv::noArray(), mask, params);
      } else {
        essential = cv::findEssentialMat(query_norm, db_norm, identity, usac_method,
                                         options.confidence, threshold, max_iterations, mask);
      }
      if (essential.rows > 3) essential = essential.rowRange(0, 3).clone();
    } else {
      const cv::Mat f = cv::findFundamentalMat(query_px, db_px, usac_method, options.max_error_px,
                                               options.confidence, max_iterations, mask);
      if (f.rows == 3 && f.cols == 3) {
        Eigen::Matrix3d fe;
        cv::cv2eigen(f, fe);
        // x_db^T F x_query = 0: the query image's epipole is F's right null vector.
        const Eigen::JacobiSVD<Eigen::Matrix3d> svd(fe, Eigen::ComputeFullV);
        const Eigen::Vector3d e = svd.matrixV().col(2);
        fundamental_e_x = e.z() != 0.0 ? e.x() / e.z() - query_camera.cx
                                       : std::numeric_limits<double>::infinity();
        essential = ToCv(db_camera.K().transpose() * fe * query_camera.K());
      }
    }
  } catch (const cv::Exception& e) {
    result.failure = std::string("estimation failed: ") + e.err;
    return result;
  }
  if (essential.rows != 3 || essential.cols != 3 || mask.empty()) {
    result.failure = "estimation failed";
    return result;
  }
  if (mask.type() != CV_8U) mask.convertTo(mask, CV_8U);
  mask = mask.reshape(1, n).clone();
  {
    const bool is_essential = options.model == EpipoleOptions::Model::kEssential;
    Eigen::Matrix3d polished;
    const bool ok =
        is_essential
            ? PolishOnInliers(query_norm, db_norm, options.max_error_px / query_camera.fx, true,
                              polished, mask)
            : PolishOnInliers(query_px, db_px, options.max_error_px, false, polished, mask);
    if (!ok) {
      result.failure = "too few inliers";
      return result;
    }
    if (is_essential) {
      essential = ToCv(polished);
    } else {
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(polished, Eigen::ComputeFullV);
      const Eigen::Vector3d e = svd.matrixV().col(2);
      fundamental_e_x =
          e.z() != 0.0 ? e.x() / e.z() - query_camera.cx : std::numeric_limits<double>::infinity();
      essential = ToCv(db_camera.K().transpose() * polished * query_camera.K());
    }
  }

  result.num_inliers = cv::countNonZero(mask);
  if (result.num_inliers < options.min_inliers) {
    result.failure = "too few inliers";
    return result;
  }
  if (result.num_inliers < options.min_inlier_ratio * n) {
    result.failure = "too small a share of inliers";
    return result;
  }

  // Cheirality fixes the sign of the translation: x_db = R x_query + t.
  cv::Mat rotation, translation;
  cv::Mat pose_mask = mask.clone();
  // Street scenes reach hundreds of baselines deep: no far-point cut (OpenCV's default is 50).
  constexpr double kFarPointDistance = 1e6;
  cv::Mat triangulated;
  const int in_front =
      cv::recoverPose(essential, query_norm, db_norm, cv::Mat::eye(3, 3, CV_64F), rotation,
                      translation, kFarPointDistance, pose_mask, triangulated);
  if (in_front < options.min_inliers) {
    result.failure = "too few inliers in front of both cameras";
    return result;
  }
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, r);
  cv::cv2eigen(translation, t);
  result.db_from_query = r;
  result.db_center_in_query = (-r.transpose() * t).normalized();
  for (int i = 0; i < n; ++i) result.inlier_mask[i] = pose_mask.at<uchar>(i) != 0;
  result.num_inliers = in_front;

  // Rotation-compensated ray angles: all zero for a pure rotation.
  std::vector<double> parallax;
  parallax.reserve(in_front);
  for (int i = 0; i < n; ++i) {
    if (!result.inlier_mask[i]) continue;
    const Eigen::Vector3d a =
        (r * Eigen::Vector3d(query_norm[i].x, query_norm[i].y, 1.0)).normalized();
    const Eigen::Vector3d b = Eigen::Vector3d(db_norm[i].x, db_norm[i].y, 1.0).normalized();
    parallax.push_back(std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / M_PI);
  }
  result.median_parallax_deg = UpperMedian(parallax);
  if (result.median_parallax_deg < options.min_parallax_deg) {
    result.failure = "no parallax (near-pure rotation)";
    return result;
  }

  const Eigen::Vector3d& q = result.db_center_in_query;
  if (options.model == EpipoleOptions::Model::kFundamental) {
    result.e_x_px = fundamental_e_x;
    result.distance =
        std::isfinite(fundamental_e_x) && fundamental_e_x != 0.0
            ? 1.0 / std::abs(fundamental_e_x)
            : (std::isinf(fundamental_e_x) ? 0.0 : std::numeric_limits<double>::infinity());
  } else {
    result.e_x_px =
        q.z() != 0.0 ? query_camera.fx * q.x() / q.z() : std::numeric_limits<double>::infinity();
    result.distance = EpipolarDistance(q, query_camera.fx);
  }
  if (!std::isfinite(result.distance)) {
    result.failure = "epipole on the principal point's vertical (no lateral offset)";
    return result;
  }
  result.signed_distance = q.z() >= 0 ? result.distance : -result.distance;
  result.valid = true;
  return result;
}

}  // namespace epiloc
