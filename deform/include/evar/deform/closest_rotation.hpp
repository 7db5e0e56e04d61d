#pragma once
// The rotation R in SO(3) maximizing tr(R^T A) (the rotational part of the polar
// decomposition, reflections excluded), as needed by ARAP's local step.
#include <Eigen/Core>

namespace evar::deform {

/// Closed form: the two dominant singular directions from the symmetric 3x3 eigenproblem
/// of AᵀA, the third by a cross product, so rank-2 A (planar one-rings) and det A < 0 need
/// no sign fix-ups. `warm` (the previous rotation) is returned when A is zero or not
/// finite; rank-1 A falls back to the SVD.
Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm = Eigen::Matrix3d::Identity());

/// Reference: SVD A = U S V^T, R = U diag(1, 1, det(U V^T)) V^T.
Eigen::Matrix3d closest_rotation_svd(const Eigen::Matrix3d& A);

}  // namespace evar::deform
