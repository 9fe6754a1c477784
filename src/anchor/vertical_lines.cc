// The world's vertical from an image's near-vertical line segments. See vertical_lines.h.
#include "epiloc/anchor/vertical_lines.h"

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

struct Segment {
  Eigen::Vector3d normal;  // of the interpretation plane, unit
  double weight;           // length over the mean length
};

// The direction most nearly in the inliers' planes: the weighted normals' smallest eigenvector,
// turned towards the camera's up (-y).
Eigen::Vector3d Refit(const std::vector<Segment>& segments, const std::vector<char>& inlier) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < segments.size(); ++i) {
    if (inlier[i]) m += segments[i].weight * segments[i].normal * segments[i].normal.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(m);
  Eigen::Vector3d v = solver.eigenvectors().col(0).normalized();
  if (v.y() > 0.0) v = -v;
  return v;
}

}  // namespace

void VerticalLinesOptions::Check() const {
  EPILOC_CHECK(std::isfinite(min_length_px) && min_length_px > 0,
               "vertical lines: min_length_px must be > 0");
  EPILOC_CHECK(
      std::isfinite(max_image_tilt_deg) && max_image_tilt_deg > 0 && max_image_tilt_deg < 90,
      "vertical lines: max_image_tilt_deg must be in (0, 90)");
  EPILOC_CHECK(
      std::isfinite(max_from_upright_deg) && max_from_upright_deg > 0 && max_from_upright_deg < 90,
      "vertical lines: max_from_upright_deg must be in (0, 90)");
  EPILOC_CHECK(std::isfinite(inlier_deg) && inlier_deg > 0,
               "vertical lines: inlier_deg must be > 0");
  EPILOC_CHECK(ransac_iterations >= 1, "vertical lines: ransac_iterations must be >= 1");
  EPILOC_CHECK(min_segments >= 3, "vertical lines: min_segments must be >= 3");
  EPILOC_CHECK(std::isfinite(floor_deg) && floor_deg >= 0,
               "vertical lines: floor_deg must be >= 0");
}

std::optional<VerticalDirection> MeasureVertical(const cv::Mat& grey,
                                                 const Camera& camera,
                                                 const VerticalLinesOptions& options) {
  options.Check();
  EPILOC_CHECK(grey.type() == CV_8UC1, "vertical lines: the image must be 8-bit grey");
  EPILOC_CHECK(grey.cols == camera.width && grey.rows == camera.height,
               "vertical lines: image size {}x{} differs from the camera's {}x{}", grey.cols,
               grey.rows, camera.width, camera.height);
  std::vector<cv::Vec4f> lines;
  cv::createLineSegmentDetector(cv::LSD_REFINE_STD)->detect(grey, lines);

  // Near-vertical segments in the image, long enough, as interpretation planes.
  const double max_tilt = std::tan(options.max_image_tilt_deg * kDegToRad);
  std::vector<Segment> segments;
  double length_sum = 0.0;
  for (const cv::Vec4f& l : lines) {
    const Eigen::Vector2d a(l[0], l[1]), b(l[2], l[3]);
    const Eigen::Vector2d d = b - a;
    const double length = d.norm();
    if (length < options.min_length_px || std::abs(d.x()) > max_tilt * std::abs(d.y())) continue;
    const Eigen::Vector2d na = camera.Unproject(a), nb = camera.Unproject(b);
    const Eigen::Vector3d n =
        Eigen::Vector3d(na.x(), na.y(), 1.0).cross(Eigen::Vector3d(nb.x(), nb.y(), 1.0));
    if (!n.allFinite() || n.norm() <= 1e-12) continue;
    segments.push_back({n.normalized(), length});
    length_sum += length;
  }
  if (static_cast<int>(segments.size()) < options.min_segments) return std::nullopt;
  const double mean_length = length_sum / static_cast<double>(segments.size());
  for (Segment& s : segments) s.weight /= mean_length;

  // RANSAC over pairs: two planes meet in a candidate direction; the one whose inliers are the
  // longest in all wins.
  const double inlier_sin = std::sin(options.inlier_deg * kDegToRad);
  const double min_up_cos = std::cos(options.max_from_upright_deg * kDegToRad);
  // The segments within inlier_deg of a plane through `v`: their summed weight, their number.
  const auto inliers_of = [&](const Eigen::Vector3d& v, double* score, int* count) {
    std::vector<char> in(segments.size(), 0);
    *score = 0.0;
    *count = 0;
    for (size_t i = 0; i < segments.size(); ++i) {
      if (std::abs(segments[i].normal.dot(v)) < inlier_sin) {
        in[i] = 1;
        *score += segments[i].weight;
        ++*count;
      }
    }
    return in;
  };
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<size_t> pick(0, segments.size() - 1);
  std::vector<char> best;
  double best_score = -1.0;
  int best_count = 0;
  for (int it = 0; it < options.ransac_iterations; ++it) {
    const size_t i = pick(rng), j = pick(rng);
    if (i == j) continue;
    Eigen::Vector3d v = segments[i].normal.cross(segments[j].normal);
    if (v.norm() <= 1e-9) continue;
    v.normalize();
    if (v.y() > 0.0) v = -v;
    if (-v.y() < min_up_cos) continue;
    double score = 0.0;
    int count = 0;
    std::vector<char> in = inliers_of(v, &score, &count);
    if (score > best_score) {
      best_score = score;
      best = std::move(in);
      best_count = count;
    }
  }
  if (best.empty()) return std::nullopt;
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  for (int round = 0; round < 3; ++round) {
    if (best_count < options.min_segments) return std::nullopt;
    v = Refit(segments, best);
    double unused_score = 0.0;
    best = inliers_of(v, &unused_score, &best_count);
  }
  if (-v.y() < min_up_cos || best_count < options.min_segments) return std::nullopt;

  VerticalDirection out;
  out.up_in_cam = v;
  out.tangent_x = (Eigen::Vector3d::UnitX() - v.x() * v).normalized();
  out.tangent_z = v.cross(out.tangent_x).normalized();
  // Covariance from the inliers' scatter: e_i = n_i . v, and a turn of v by (a, b) along the
  // tangents changes it by a n_i . t_x + b n_i . t_z.
  Eigen::Matrix2d information = Eigen::Matrix2d::Zero();
  double weighted_sq = 0.0;
  for (size_t i = 0; i < segments.size(); ++i) {
    if (!best[i]) continue;
    const Segment& s = segments[i];
    const Eigen::Vector2d j(s.normal.dot(out.tangent_x), s.normal.dot(out.tangent_z));
    const double e = s.normal.dot(v);
    information += s.weight * j * j.transpose();
    weighted_sq += s.weight * e * e;
  }
  out.segments = best_count;
  const double variance = std::max(weighted_sq / static_cast<double>(best_count - 2), 1e-14);
  // Two or more planes at an angle to each other fix both axes; all in one plane fix one.
  if (!(information.determinant() > 1e-12 * information.squaredNorm())) return std::nullopt;
  const double floor = options.floor_deg * kDegToRad;
  out.covariance = variance * information.inverse() + floor * floor * Eigen::Matrix2d::Identity();
  return out;
}

}  // namespace epiloc
