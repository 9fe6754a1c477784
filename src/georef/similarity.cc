#include "epiloc/georef/similarity.h"

#include <algorithm>
#include <cmath>

#include <Eigen/SVD>
#include <unsupported/Eigen/MatrixFunctions>

#include "epiloc/core/error.h"

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
