#include "evar/deform/closest_rotation.hpp"

#include <Eigen/Geometry>
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
  Eigen::Quaterniond q(warm);
  q.normalize();
  // Each step rotates R by the axis-angle ω = Σ_k r_k × a_k / |Σ_k r_k · a_k| (columns),
  // a damped Newton step on tr(R^T A); it stops when the step is negligible.
  constexpr int kMaxSteps = 40;
  for (int step = 0; step < kMaxSteps; ++step) {
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const Eigen::Vector3d omega_num = R.col(0).cross(A.col(0)) + R.col(1).cross(A.col(1)) + R.col(2).cross(A.col(2));
    const double denom = std::abs(R.col(0).dot(A.col(0)) + R.col(1).dot(A.col(1)) + R.col(2).dot(A.col(2))) + 1e-12 * scale;
    const Eigen::Vector3d omega = omega_num / denom;
    const double w = omega.norm();
    if (w < 1e-10) {
      // A stationary point is the maximum iff H = tr(S) I - S is positive semidefinite,
      // S = sym(R^T A) (second-order condition on SO(3)); saddles (a warm start about
      // 180 degrees off) go to the SVD. PSD via all principal minors (cheap, 3x3).
      const Eigen::Matrix3d M = R.transpose() * A;
      const Eigen::Matrix3d S = 0.5 * (M + M.transpose());
      const Eigen::Matrix3d H = S.trace() * Eigen::Matrix3d::Identity() - S;
      const double tol = 1e-9 * scale;
      const bool psd = H(0, 0) >= -tol && H(1, 1) >= -tol && H(2, 2) >= -tol &&
                       H(0, 0) * H(1, 1) - H(0, 1) * H(1, 0) >= -tol * scale &&
                       H(0, 0) * H(2, 2) - H(0, 2) * H(2, 0) >= -tol * scale &&
                       H(1, 1) * H(2, 2) - H(1, 2) * H(2, 1) >= -tol * scale &&
                       H.determinant() >= -tol * scale * scale;
      return psd ? R : closest_rotation_svd(A);
    }
    q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * q;
    q.normalize();
  }
  return closest_rotation_svd(A);
}

}  // namespace evar::deform
