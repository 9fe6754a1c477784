#include "epiloc/georef/similarity.h"

#include <algorithm>
#include <cmath>

#include <Eigen/SVD>
#include <unsupported/Eigen/MatrixFunctions>

#include "epiloc/core/error.h"
#include "epiloc/geo/rigid3.h"

namespace epiloc {

Sim3d Sim3d::Inverse() const {
  Sim3d inverse;
  inverse.scale = 1.0 / scale;
  inverse.rotation = rotation.conjugate();
  inverse.translation = -(inverse.scale * (inverse.rotation * translation));
  return inverse;
}

std::optional<Sim3d> FitSim3(const std::vector<Eigen::Vector3d>& source,
                             const std::vector<Eigen::Vector3d>& target,
                             double min_spread_ratio) {
  EPILOC_CHECK(source.size() == target.size(), "FitSim3: {} source but {} target points",
               source.size(), target.size());
  const int n = static_cast<int>(source.size());
  if (n < 3) return std::nullopt;
  Eigen::Matrix3Xd src(3, n), dst(3, n);
  for (int i = 0; i < n; ++i) {
    src.col(i) = source[static_cast<size_t>(i)];
    dst.col(i) = target[static_cast<size_t>(i)];
  }
  const Eigen::Matrix3Xd centred = src.colwise() - src.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(centred);
  const Eigen::Vector3d sigma = svd.singularValues();
  if (!(sigma[0] > 0.0) || sigma[1] < min_spread_ratio * sigma[0]) return std::nullopt;
  const Eigen::Matrix4d m = Eigen::umeyama(src, dst, true);
  Sim3d sim;
  const Eigen::Matrix3d sr = m.topLeftCorner<3, 3>();
  sim.scale = std::cbrt(sr.determinant());
  if (!(sim.scale > 0.0) || !std::isfinite(sim.scale)) return std::nullopt;
  sim.rotation = Eigen::Quaterniond(Eigen::Matrix3d(sr / sim.scale)).normalized();
  sim.translation = m.topRightCorner<3, 1>();
  return sim;
}

std::optional<Sim3d> FitSim3(const std::vector<Eigen::Vector3d>& source,
                             const std::vector<Eigen::Vector3d>& target,
                             const std::vector<Eigen::Quaterniond>& target_from_source) {
  EPILOC_CHECK(source.size() == target.size() && source.size() == target_from_source.size(),
               "FitSim3: {} source points, {} target points, {} rotations", source.size(),
               target.size(), target_from_source.size());
  const size_t n = source.size();
  if (n < 2) return std::nullopt;
  Eigen::Vector3d source_mean = Eigen::Vector3d::Zero(), target_mean = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    source_mean += source[i];
    target_mean += target[i];
  }
  source_mean /= static_cast<double>(n);
  target_mean /= static_cast<double>(n);
  double source_spread = 0.0, target_spread = 0.0;
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d rotations = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = source[i] - source_mean;
    const Eigen::Vector3d y = target[i] - target_mean;
    source_spread += x.squaredNorm();
    target_spread += y.squaredNorm();
    cross += y * x.transpose();
    rotations += target_from_source[i].normalized().toRotationMatrix();
  }
  if (!(source_spread > 0.0) || !(target_spread > 0.0)) return std::nullopt;
  // cross ~ s R sum(x x^T): divided by s * sum |x|^2 it weighs R's columns by the share of the
  // spread along each source axis (total 1), as much as the mean rotation weighs each.
  const double scale_guess = std::sqrt(target_spread / source_spread);
  const Eigen::Matrix3d m =
      cross / (scale_guess * source_spread) + rotations / static_cast<double>(n);
  const Eigen::Matrix3d r = NearestRotation(m);
  Sim3d sim;
  sim.scale = (cross.cwiseProduct(r)).sum() / source_spread;  // sum y . R x / sum |x|^2
  if (!(sim.scale > 0.0) || !std::isfinite(sim.scale)) return std::nullopt;
  sim.rotation = Eigen::Quaterniond(r).normalized();
  sim.translation = target_mean - sim.scale * (r * source_mean);
  return sim;
}

FitResiduals Residuals(const Sim3d& sim,
                       const std::vector<Eigen::Vector3d>& source,
                       const std::vector<Eigen::Vector3d>& target) {
  FitResiduals r;
  if (source.empty()) return r;
  double sum = 0.0;
  for (size_t i = 0; i < source.size(); ++i) {
    const double e = (target[i] - sim * source[i]).norm();
    sum += e * e;
    r.max_m = std::max(r.max_m, e);
  }
  r.rms_m = std::sqrt(sum / static_cast<double>(source.size()));
  return r;
}

}  // namespace epiloc
