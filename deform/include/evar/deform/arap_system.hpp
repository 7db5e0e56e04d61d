#pragma once
// The ARAP energy written as a sum of edge terms, so that the surface one-rings
// (Sorkine & Alexa 2007, eq. 1) and the skeleton (Zhang et al. 2010, L_s) share one
// solver:
//
//   E(x, R) = Σ_t w_t ‖ Σ_k a_tk x_k − R_c(t) e_t ‖²,   e_t = Σ_k a_tk x̄_k (rest),
//
// x the deformed unknowns (#V surface vertices first, then skeleton points), x̄ their
// rest positions, R_c one rotation per cell. For a surface half-edge (i, j) in the cell
// of i: a = (+1 at i, -1 at j), w = w_ij (cotangent). The system matrix of the global
// step, A = Σ_t w_t a_t a_tᵀ, is the paper's L (stacked with L_s); the right-hand side
// Σ_t w_t a_t (R_c e_t)ᵀ is b(R).
#include <Eigen/Core>
#include <Eigen/Sparse>
#include <vector>

#include "evar/deform/cotangent_weights.hpp"

namespace evar::deform {

struct ArapTerms {
  int num_unknowns = 0;
  int num_cells = 0;
  /// Terms are stored grouped by cell: cell c owns terms [cell_begin[c], cell_begin[c+1]).
  std::vector<int> cell_begin{0};
  std::vector<double> weight;             ///< w_t
  std::vector<int> coeff_begin{0};        ///< CSR over terms: coefficients of term t are
  std::vector<int> coeff_index;           ///<   [coeff_begin[t], coeff_begin[t+1])
  std::vector<double> coeff_value;
  std::vector<Eigen::Vector3d> rest;      ///< e_t (mm)

  int num_terms() const { return static_cast<int>(weight.size()); }
  /// Starts a new cell; following add_term calls belong to it.
  void begin_cell();
  /// Adds a term to the current cell; `rest` must equal Σ a_k x̄_k.
  void add_term(double w, std::initializer_list<std::pair<int, double>> coeffs, const Eigen::Vector3d& rest);
  void add_term(double w, const std::vector<std::pair<int, double>>& coeffs, const Eigen::Vector3d& rest);
};

/// Surface ARAP terms: one cell per vertex holding the half-edges to its one-ring,
/// weighted by cotangent weights. `num_unknowns` may exceed #V to leave room for skeleton
/// points appended later (their cells come after the #V vertex cells).
ArapTerms surface_arap_terms(const geometry::Vertices& V,
                             const std::vector<WeightedEdge>& edges, int num_unknowns);

/// A = Σ_t w_t a_t a_tᵀ (#unknowns square, symmetric positive semidefinite).
Eigen::SparseMatrix<double> assemble_system_matrix(const ArapTerms& terms);

}  // namespace evar::deform
