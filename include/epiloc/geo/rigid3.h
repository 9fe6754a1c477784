// Rigid transforms. Convention: b_from_a maps a point from frame a to frame b,
// x_in_b = rotation * x_in_a + translation.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epiloc {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& r, const Eigen::Vector3d& t) : rotation(r), translation(t) {}
  static Rigid3d FromMatrix(const Eigen::Matrix3d& r, const Eigen::Vector3d& t);

  Eigen::Vector3d operator*(const Eigen::Vector3d& x_in_a) const {
    return rotation * x_in_a + translation;
  }
  // c_from_b * b_from_a = c_from_a.
  Rigid3d operator*(const Rigid3d& b_from_a) const {
    return Rigid3d(rotation * b_from_a.rotation, rotation * b_from_a.translation + translation);
  }
  Rigid3d Inverse() const;
  Eigen::Matrix<double, 3, 4> ToMatrix3x4() const;
};

// The rotation nearest a 3x3 matrix in the Frobenius norm (U diag(1, 1, det(U V^T)) V^T of its
// SVD): e.g. of a sum of rotations, their chordal mean.
Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m);

// Angle of the relative rotation between two orientations, degrees in [0, 180].
double RotationDifferenceDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace epiloc
