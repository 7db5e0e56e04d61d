#include "closest_rotation.hpp"

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

namespace {

// Newton's method on SO(3) from the warm start, for the ARAP iterations where the
// rotations move little from one local step to the next. With R = R0·Q(ω), M = R0ᵀA:
//   tr(RᵀA) ≈ tr M + gᵀω − ½ ωᵀHω,   g = vee(M − Mᵀ),  H = tr(M)·I − sym(M),
// Q the Cayley map (a rotation that agrees with exp[ω]× to second order, no trig).
// Steps are taken only while H is positive definite, i.e. towards a maximum; at a
// critical point with H positive definite, R is the global maximizer (the other
// critical points of tr(RᵀA) on SO(3) are saddles or minima). Returns false when that
// cannot be certified, and the closed form decides.
// `max_steps` Newton steps at most; the result is accepted once a step is shorter than
// `accept_step_rad`.
bool newton_rotation(const Eigen::Matrix3d& An, const Eigen::Matrix3d& warm, int max_steps, double accept_step_rad,
                     Eigen::Matrix3d& R) {
  R = warm;
  for (int step = 0; step < max_steps; ++step) {
    const Eigen::Matrix3d M = R.transpose() * An;
    const Eigen::Vector3d g(M(2, 1) - M(1, 2), M(0, 2) - M(2, 0), M(1, 0) - M(0, 1));
    const double tr = M.trace();
    Eigen::Matrix3d H = -0.5 * (M + M.transpose());
    H.diagonal().array() += tr;
    // Sylvester's criterion with a margin relative to |A| = 1: H well inside the cone.
    const double m1 = H(0, 0);
    const double m2 = H(0, 0) * H(1, 1) - H(0, 1) * H(1, 0);
    const Eigen::Matrix3d adj = [&] {
      Eigen::Matrix3d C;
      C(0, 0) = H(1, 1) * H(2, 2) - H(1, 2) * H(2, 1);
      C(0, 1) = H(0, 2) * H(2, 1) - H(0, 1) * H(2, 2);
      C(0, 2) = H(0, 1) * H(1, 2) - H(0, 2) * H(1, 1);
      C(1, 1) = H(0, 0) * H(2, 2) - H(0, 2) * H(2, 0);
      C(1, 2) = H(0, 2) * H(1, 0) - H(0, 0) * H(1, 2);
      C(2, 2) = m2;
      C(1, 0) = C(0, 1);
      C(2, 0) = C(0, 2);
      C(2, 1) = C(1, 2);
      return C;
    }();
    const double m3 = H(0, 0) * adj(0, 0) + H(0, 1) * adj(1, 0) + H(0, 2) * adj(2, 0);
    constexpr double kMargin = 1e-6;
    if (!(m1 > kMargin && m2 > kMargin && m3 > kMargin)) return false;
    const Eigen::Vector3d w = adj * g * (1.0 / m3);  // ω = H⁻¹ g
    const double w2 = w.squaredNorm();
    if (!(w2 < 1.0)) return false;  // a long step: far from the maximum, not Newton's regime
    // Cayley: unit quaternion ∝ (1, ω/2).
    const double qn = 1.0 / (1.0 + 0.25 * w2);
    const double x = 0.5 * w.x(), y = 0.5 * w.y(), z = 0.5 * w.z();
    Eigen::Matrix3d Q;
    Q << 1.0 - 2.0 * qn * (y * y + z * z), 2.0 * qn * (x * y - z), 2.0 * qn * (x * z + y),
        2.0 * qn * (x * y + z), 1.0 - 2.0 * qn * (x * x + z * z), 2.0 * qn * (y * z - x),
        2.0 * qn * (x * z - y), 2.0 * qn * (y * z + x), 1.0 - 2.0 * qn * (x * x + y * y);
    R = R * Q;
    if (w2 < accept_step_rad * accept_step_rad) return R.allFinite();
  }
  return false;
}

}  // namespace

Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm) {
  const double scale = A.norm();
  if (!(scale > 0.0) || !A.allFinite()) return warm;  // no information: keep the rotation
  // Quadratic convergence: after a step of 1e-5 rad the error is about 1e-10.
  if (Eigen::Matrix3d R; newton_rotation(A / scale, warm, 4, 1e-5, R)) return R;
  return closest_rotation_closed_form(A);
}

Eigen::Matrix3d refine_rotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& warm) {
  const double scale = A.norm();
  if (!(scale > 0.0) || !A.allFinite()) return warm;
  if (Eigen::Matrix3d R; newton_rotation(A * (1.0 / scale), warm, 1, 0.1, R)) return R;
  return closest_rotation(A, warm);
}

namespace {

// One Newton step of newton_rotation (same formulas, same acceptance) for kLanes cells in
// structure-of-arrays form: every statement is a loop over the lanes, which the compiler
// vectorizes. Matrices are column-major, a[3 * col + row][lane]. ok[l] says whether lane l's
// step was certified and short; otherwise the caller decides that cell on its own.
constexpr int kLanes = 8;
using Lanes = double[kLanes];

void newton_step_lanes(const double (&a)[9][kLanes], const double (&r0)[9][kLanes], double (&r)[9][kLanes],
                       bool (&ok)[kLanes]) {
  double m[9][kLanes];  // M = R0ᵀ A
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int l = 0; l < kLanes; ++l)
        m[3 * j + i][l] = r0[3 * i][l] * a[3 * j][l] + r0[3 * i + 1][l] * a[3 * j + 1][l] + r0[3 * i + 2][l] * a[3 * j + 2][l];
  Lanes g0, g1, g2, h00, h11, h22, h01, h02, h12;
  for (int l = 0; l < kLanes; ++l) {
    g0[l] = m[5][l] - m[7][l];  // M(2,1) − M(1,2)
    g1[l] = m[6][l] - m[2][l];  // M(0,2) − M(2,0)
    g2[l] = m[1][l] - m[3][l];  // M(1,0) − M(0,1)
    const double tr = m[0][l] + m[4][l] + m[8][l];
    h00[l] = tr - m[0][l];
    h11[l] = tr - m[4][l];
    h22[l] = tr - m[8][l];
    h01[l] = -0.5 * (m[3][l] + m[1][l]);
    h02[l] = -0.5 * (m[6][l] + m[2][l]);
    h12[l] = -0.5 * (m[7][l] + m[5][l]);
  }
  constexpr double kMargin = 1e-6;
  Lanes w2, x, y, z;
  for (int l = 0; l < kLanes; ++l) {
    const double c00 = h11[l] * h22[l] - h12[l] * h12[l];
    const double c01 = h02[l] * h12[l] - h01[l] * h22[l];
    const double c02 = h01[l] * h12[l] - h02[l] * h11[l];
    const double c11 = h00[l] * h22[l] - h02[l] * h02[l];
    const double c12 = h02[l] * h01[l] - h00[l] * h12[l];
    const double m2 = h00[l] * h11[l] - h01[l] * h01[l];
    const double m3 = h00[l] * c00 + h01[l] * c01 + h02[l] * c02;
    const double inv = 1.0 / m3;
    const double w0 = (c00 * g0[l] + c01 * g1[l] + c02 * g2[l]) * inv;
    const double w1 = (c01 * g0[l] + c11 * g1[l] + c12 * g2[l]) * inv;
    const double wz = (c02 * g0[l] + c12 * g1[l] + m2 * g2[l]) * inv;
    w2[l] = w0 * w0 + w1 * w1 + wz * wz;
    ok[l] = h00[l] > kMargin && m2 > kMargin && m3 > kMargin && w2[l] < 0.1 * 0.1;
    x[l] = 0.5 * w0;
    y[l] = 0.5 * w1;
    z[l] = 0.5 * wz;
  }
  double q[9][kLanes];  // Cayley: unit quaternion ∝ (1, ω/2)
  for (int l = 0; l < kLanes; ++l) {
    const double qn2 = 2.0 / (1.0 + 0.25 * w2[l]);
    q[0][l] = 1.0 - qn2 * (y[l] * y[l] + z[l] * z[l]);
    q[1][l] = qn2 * (x[l] * y[l] + z[l]);
    q[2][l] = qn2 * (x[l] * z[l] - y[l]);
    q[3][l] = qn2 * (x[l] * y[l] - z[l]);
    q[4][l] = 1.0 - qn2 * (x[l] * x[l] + z[l] * z[l]);
    q[5][l] = qn2 * (y[l] * z[l] + x[l]);
    q[6][l] = qn2 * (x[l] * z[l] + y[l]);
    q[7][l] = qn2 * (y[l] * z[l] - x[l]);
    q[8][l] = 1.0 - qn2 * (x[l] * x[l] + y[l] * y[l]);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int l = 0; l < kLanes; ++l)
        r[3 * j + i][l] = r0[i][l] * q[3 * j][l] + r0[3 + i][l] * q[3 * j + 1][l] + r0[6 + i][l] * q[3 * j + 2][l];
}

}  // namespace

void refine_rotations(const Eigen::Matrix3d* A, const Eigen::Matrix3d* warm, Eigen::Matrix3d* R, int count) {
  int c0 = 0;
  for (; c0 + kLanes <= count; c0 += kLanes) {
    double a[9][kLanes], r0[9][kLanes], r[9][kLanes];
    bool ok[kLanes];
    Lanes scale;
    for (int l = 0; l < kLanes; ++l) {
      const double* src = A[c0 + l].data();
      double s2 = 0.0;
      for (int e = 0; e < 9; ++e) s2 += src[e] * src[e];
      scale[l] = std::sqrt(s2);
    }
    for (int l = 0; l < kLanes; ++l) {
      const double inv = 1.0 / scale[l];
      for (int e = 0; e < 9; ++e) {
        a[e][l] = A[c0 + l].data()[e] * inv;
        r0[e][l] = warm[c0 + l].data()[e];
      }
    }
    newton_step_lanes(a, r0, r, ok);
    for (int l = 0; l < kLanes; ++l) {
      Eigen::Matrix3d Rl, warm_l;  // warm_l: R may be warm, so its copy
      for (int e = 0; e < 9; ++e) {
        Rl.data()[e] = r[e][l];
        warm_l.data()[e] = r0[e][l];
      }
      // As refine_rotation: a zero or non-finite A, an uncertified or long step, or a
      // non-finite result is decided by the scalar path.
      if (ok[l] && scale[l] > 0.0 && Rl.allFinite() && A[c0 + l].allFinite())
        R[c0 + l] = Rl;
      else
        R[c0 + l] = refine_rotation(A[c0 + l], warm_l);
    }
  }
  for (int c = c0; c < count; ++c) R[c] = refine_rotation(A[c], warm[c]);
}

Eigen::Matrix3d closest_rotation_closed_form(const Eigen::Matrix3d& A) {
  const double scale = A.norm();
  if (!(scale > 0.0) || !A.allFinite()) return Eigen::Matrix3d::Identity();
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
