#pragma once
// The rotation R in SO(3) maximizing tr(R^T A) (the rotational part of the polar
// decomposition, reflections excluded), as needed by ARAP's local step.
#include <Eigen/Core>

namespace evar::deform {

/// Iterative solver of Müller, Bender, Chentanez, Macklin 2016 ("A robust method to
/// extract the rotational part of deformations"), warm-started from `warm` (the previous
/// iteration's rotation, so it usually needs 1-3 steps). It converges to the maximizer also
/// for rank-2 A (planar one-rings), where an SVD needs a careful sign fix. If it has not
/// converged after its step budget, falls back to an SVD with the determinant fix.
Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm = Eigen::Matrix3d::Identity());

/// Reference: SVD A = U S V^T, R = U diag(1, 1, det(U V^T)) V^T.
Eigen::Matrix3d closest_rotation_svd(const Eigen::Matrix3d& A);

}  // namespace evar::deform
