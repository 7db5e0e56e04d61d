#pragma once
// The rotation R in SO(3) maximizing tr(R^T A) (the rotational part of the polar
// decomposition, reflections excluded), as needed by ARAP's local step.
#include <Eigen/Core>

namespace evar::deform {

/// Newton's method on SO(3) from `warm` while it is near the maximizer (a few steps of
/// about 50 flops, quadratic convergence, certified by a positive definite Hessian),
/// else the closed form below. `warm` (the previous rotation) is returned when A is zero
/// or not finite.
Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm = Eigen::Matrix3d::Identity());

/// ARAP's local step: a single Newton step from the previous rotation when it is within
/// Newton's regime (step under 0.1 rad), else closest_rotation. The error left is about
/// the square of the step, and the steps vanish as the iteration converges, so the
/// fixed point is that of the exact local step.
Eigen::Matrix3d refine_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm);

/// refine_rotation for `count` cells at once: R[i] from A[i] and warm[i] (R may be warm).
/// The Newton step is taken for eight cells side by side in structure-of-arrays form, so
/// the compiler turns it into vector instructions; a cell outside Newton's regime gets
/// refine_rotation's fallback. Same result as refine_rotation, up to rounding.
void refine_rotations(const Eigen::Matrix3d* A, const Eigen::Matrix3d* warm, Eigen::Matrix3d* R, int count);

/// Closed form: the two dominant singular directions from the symmetric 3x3 eigenproblem
/// of AᵀA, the third by a cross product, so rank-2 A (planar one-rings) and det A < 0 need
/// no sign fix-ups; rank-1 A falls back to the SVD.
Eigen::Matrix3d closest_rotation_closed_form(const Eigen::Matrix3d& A);

/// Reference: SVD A = U S V^T, R = U diag(1, 1, det(U V^T)) V^T.
Eigen::Matrix3d closest_rotation_svd(const Eigen::Matrix3d& A);

}  // namespace evar::deform
