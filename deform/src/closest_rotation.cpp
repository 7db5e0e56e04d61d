#include "evar/deform/closest_rotation.hpp"

#include <Eigen/Geometry>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>

namespace evar::deform {

Eigen::Matrix3d closest_rotation_svd(const Eigen::Matrix3d& A) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) = -U.col(2);  // smallest singular value
  return U * V.transpose();
}

Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm) {
  const double scale = A.norm();
  if (!(scale > 0.0) || !A.allFinite()) return warm;  // no information: keep the rotation
  // AᵀA = V Σ² Vᵀ in closed form; u_i = A v_i / σ_i for the two largest σ. Then
  // R = [u1, u2, u1 × u2] Vᵀ (V made proper) is U diag(1, 1, sign det A) Vᵀ, the maximizer
  // of tr(RᵀA) over SO(3), whether A is full rank, rank 2 (a planar one-ring) or mirrored:
  // the smallest singular direction never has to be computed.
  // Scaled to unit norm so AᵀA neither underflows nor overflows.
  const Eigen::Matrix3d An = A / scale;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(An.transpose() * An);  // eigenvalues ascending
  // Near rank 1 the second direction from AᵀA is rounding noise: let the SVD decide.
  if (eig.eigenvalues()(1) < 1e-10 * eig.eigenvalues()(2)) return closest_rotation_svd(A);
  Eigen::Matrix3d V = eig.eigenvectors();
  const Eigen::Vector3d v1 = V.col(2), v2 = V.col(1);
  Eigen::Vector3d u1 = An * v1;
  const double s1 = u1.norm();
  if (!(s1 > 1e-12)) return closest_rotation_svd(A);
  u1 /= s1;
  Eigen::Vector3d u2 = An * v2;
  u2 -= u2.dot(u1) * u1;  // Gram-Schmidt against rounding
  const double s2 = u2.norm();
  // Rank 1 (all edges of the cell collinear): the rotation about that line is free;
  // the SVD picks one, and the warm start would serve as well.
  if (!(s2 > 1e-9)) return closest_rotation_svd(A);
  u2 /= s2;
  Eigen::Matrix3d U, Vp;
  U << u1, u2, u1.cross(u2);
  Vp << v1, v2, v1.cross(v2);
  const Eigen::Matrix3d R = U * Vp.transpose();
  if (!R.allFinite()) return closest_rotation_svd(A);
  return R;
}

}  // namespace evar::deform
