#include "epiloc/geo/rigid3.h"

#include <cmath>

#include <Eigen/SVD>

namespace epiloc {

Rigid3d Rigid3d::FromMatrix(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  return Rigid3d(Eigen::Quaterniond(r).normalized(), t);
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inverse = rotation.conjugate();
  return Rigid3d(inverse, -(inverse * translation));
}

Eigen::Matrix<double, 3, 4> Rigid3d::ToMatrix3x4() const {
  Eigen::Matrix<double, 3, 4> m;
  m.leftCols<3>() = rotation.toRotationMatrix();
  m.col(3) = translation;
  return m;
}

Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

double RotationDifferenceDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b) * 180.0 / M_PI;
}

}  // namespace epiloc
