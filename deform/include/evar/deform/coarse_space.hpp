#pragma once
// A coarse correction for the motions local/global iterations are slowest on. The global
// step's matrix A prices every motion as if the rotations held still, so motions that turn
// whole lengths of the vessel (a length beyond the handles hinging about the line of
// handles on its wall, or twisting about its axis) look stiff to it although their true
// energy barely changes: each iteration undoes a few per cent of them. The coarse space
// holds exactly those motions, a rigid motion (ω, t) per knot along the vessel, blended
// between neighbouring knots by hat functions of arc length:
//
//   δx_k = Σ_s φ_s(k) (ω_s × (x̄_k − c_s) + t_s),   each cell's rotation turning by Σ_s φ_s(c) ω_s.
//
// Its Gauss-Newton matrix N = Σ_t w_t J_tᵀ J_t (+ tether), with the rotations turning along,
// sees their true cost: inside a knot's reach a term only turns; only the blending and the
// tether price the motion. N is assembled once, at rest, and per constraint set the held
// unknowns' motion is taken out. The solver uses the step ξ = −N⁻¹ Bᵀ (A x − b(R)) (the
// energy's gradient brought into the coarse space) to turn the rotations before each
// global solve, R_c ← exp([Ω_c]×) R_c: the global step then places the turned lengths
// where their true energy wants them, instead of a few per cent of the way.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "evar/deform/arap_system.hpp"

namespace evar::deform {

/// Where the unknowns lie along the shape's axis, and where they are at rest.
struct ArapKnots {
  std::vector<double> arc_of_unknown;  ///< mm along the axis; empty: no coarse space
  geometry::Vertices rest;  ///< x̄, one row per unknown
  double spacing_mm = 20.0;            ///< between knots
};

class CoarseSpace {
 public:
  /// Throws std::invalid_argument unless there is an arc and a rest position per unknown,
  /// the spacing is positive and no cell lacks its unknown (cell c lies where unknown c does).
  CoarseSpace(const ArapTerms& terms, const std::vector<double>& tether_weight, const ArapKnots& knots);

  int knots() const { return knots_; }
  const std::vector<Eigen::Vector3d>& centres() const { return centre_; }  ///< c_s, at rest
  const Eigen::MatrixXd& matrix() const { return N_; }  ///< N (6·knots square), nothing held
  /// N for a constraint set, factored: the `held` unknowns do not move with the knots.
  /// `terms` and `tether_weight` are those given to the constructor.
  Eigen::LDLT<Eigen::MatrixXd> factor_holding(const ArapTerms& terms, const std::vector<double>& tether_weight,
                                              const std::vector<int>& held) const;
  /// Bᵀ v over the unknowns not skipped (v: #unknowns by 3).
  Eigen::VectorXd project(const Eigen::MatrixXd& v, const std::vector<char>& skip) const;
  /// R_c ← cay(Ω_c) R_c, Ω_c = Σ_s φ_s(c) ω_s: each cell turned by the knots' rotations
  /// (the Cayley rotation, equal to exp([Ω]×) to second order).
  void turn_cells(const Eigen::VectorXd& xi, std::vector<Eigen::Matrix3d>& R) const;

 private:
  struct Entry {
    int s0 = 0;                 // knots s0 and s0 + 1
    double f0 = 0.0, f1 = 0.0;  // their hat weights
    Eigen::Vector3d y0, y1;     // x̄ − c_s0, x̄ − c_s0+1
  };
  // Adds sign · w_t J_tᵀ J_t of term t to N, the `still` unknowns not moving.
  void add_term(const ArapTerms& terms, int t, const std::vector<char>& still, double sign, Eigen::MatrixXd& N) const;
  void add_tether(int k, double w, Eigen::MatrixXd& N) const;

  std::vector<Entry> at_;
  std::vector<Eigen::Vector3d> centre_;
  int knots_ = 0;
  Eigen::MatrixXd N_;
  std::vector<int> term_cell_;               // the cell of each term
  std::vector<int> terms_of_, term_list_;    // CSR: the terms each unknown appears in
};

}  // namespace evar::deform
