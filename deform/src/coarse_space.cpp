#include "evar/deform/coarse_space.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace evar::deform {
namespace {

Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// The motion of one unknown per unit ξ of the knots it lies between: δx = J ξ, J 3 × 12
// over (knot s0, knot s0+1), each block [−[y]×, I] scaled by the hat weight.
Eigen::Matrix<double, 3, 12> motion(const Eigen::Vector3d& y0, double f0, const Eigen::Vector3d& y1, double f1) {
  Eigen::Matrix<double, 3, 12> J;
  J.block<3, 3>(0, 0) = -f0 * cross_matrix(y0);
  J.block<3, 3>(0, 3) = f0 * Eigen::Matrix3d::Identity();
  J.block<3, 3>(0, 6) = -f1 * cross_matrix(y1);
  J.block<3, 3>(0, 9) = f1 * Eigen::Matrix3d::Identity();
  return J;
}

}  // namespace

CoarseSpace::CoarseSpace(const ArapTerms& terms, const std::vector<double>& tether_weight, const ArapKnots& knots) {
  const int n = terms.num_unknowns;
  if (knots.arc_of_unknown.size() != static_cast<std::size_t>(n) || knots.rest.rows() != n ||
      !(knots.spacing_mm > 0.0) || terms.num_cells > n || n == 0)
    throw std::invalid_argument(
        "ARAP coarse space: an arc length and a rest position per unknown, a positive knot spacing, and no more cells "
        "than unknowns are required");
  const auto [lo, hi] = std::minmax_element(knots.arc_of_unknown.begin(), knots.arc_of_unknown.end());
  const double start = *lo, length = std::max(*hi - *lo, 1e-9);
  knots_ = std::max(2, static_cast<int>(std::ceil(length / knots.spacing_mm)) + 1);
  const double h = length / (knots_ - 1);
  // Hat weights, then each knot's centre: the weighted mean of the rest positions it moves.
  at_.resize(static_cast<std::size_t>(n));
  std::vector<Eigen::Vector3d>& centre = centre_;
  centre.assign(static_cast<std::size_t>(knots_), Eigen::Vector3d::Zero());
  std::vector<double> mass(static_cast<std::size_t>(knots_), 0.0);
  for (int k = 0; k < n; ++k) {
    const double v = std::clamp((knots.arc_of_unknown[static_cast<std::size_t>(k)] - start) / h, 0.0, knots_ - 1.0);
    Entry& e = at_[static_cast<std::size_t>(k)];
    e.s0 = std::min(static_cast<int>(v), knots_ - 2);
    e.f1 = v - e.s0;
    e.f0 = 1.0 - e.f1;
    const Eigen::Vector3d p = knots.rest.row(k).transpose();
    centre[static_cast<std::size_t>(e.s0)] += e.f0 * p;
    centre[static_cast<std::size_t>(e.s0 + 1)] += e.f1 * p;
    mass[static_cast<std::size_t>(e.s0)] += e.f0;
    mass[static_cast<std::size_t>(e.s0 + 1)] += e.f1;
  }
  for (int s = 0; s < knots_; ++s)
    if (mass[static_cast<std::size_t>(s)] > 0) centre[static_cast<std::size_t>(s)] /= mass[static_cast<std::size_t>(s)];
  for (int k = 0; k < n; ++k) {
    Entry& e = at_[static_cast<std::size_t>(k)];
    const Eigen::Vector3d p = knots.rest.row(k).transpose();
    e.y0 = p - centre[static_cast<std::size_t>(e.s0)];
    e.y1 = p - centre[static_cast<std::size_t>(e.s0 + 1)];
  }

  // N = Σ_t w_t J_tᵀ J_t at rest (R = I, q = e_t), J_t = Σ_k a_k J_k + the cell's turn.
  N_ = Eigen::MatrixXd::Zero(6 * knots_, 6 * knots_);
  term_cell_.assign(static_cast<std::size_t>(terms.num_terms()), 0);
  for (int c = 0; c < terms.num_cells; ++c)
    for (int t = terms.cell_begin[static_cast<std::size_t>(c)]; t < terms.cell_begin[static_cast<std::size_t>(c) + 1]; ++t)
      term_cell_[static_cast<std::size_t>(t)] = c;
  const std::vector<char> none(static_cast<std::size_t>(n), 0);
  for (int t = 0; t < terms.num_terms(); ++t) add_term(terms, t, none, 1.0, N_);
  for (int k = 0; k < n && !tether_weight.empty(); ++k) add_tether(k, tether_weight[static_cast<std::size_t>(k)], N_);
  // Which terms each unknown appears in (for a constraint set's corrections).
  terms_of_.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int t = 0; t < terms.num_terms(); ++t)
    for (int p = terms.coeff_begin[static_cast<std::size_t>(t)]; p < terms.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p)
      ++terms_of_[static_cast<std::size_t>(terms.coeff_index[static_cast<std::size_t>(p)]) + 1];
  for (int k = 0; k < n; ++k) terms_of_[static_cast<std::size_t>(k) + 1] += terms_of_[static_cast<std::size_t>(k)];
  term_list_.resize(static_cast<std::size_t>(terms_of_.back()));
  std::vector<int> fill(terms_of_.begin(), terms_of_.end() - 1);
  for (int t = 0; t < terms.num_terms(); ++t)
    for (int p = terms.coeff_begin[static_cast<std::size_t>(t)]; p < terms.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p)
      term_list_[static_cast<std::size_t>(fill[static_cast<std::size_t>(terms.coeff_index[static_cast<std::size_t>(p)])]++)] = t;
}

void CoarseSpace::add_term(const ArapTerms& terms, int t, const std::vector<char>& still, double sign,
                           Eigen::MatrixXd& N) const {
  constexpr int kSpan = 4;  // knots a term may reach: its unknowns and cell lie within a few
  const Entry& ec = at_[static_cast<std::size_t>(term_cell_[static_cast<std::size_t>(t)])];
  int first = ec.s0, last = ec.s0 + 1;
  for (int p = terms.coeff_begin[static_cast<std::size_t>(t)]; p < terms.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p) {
    const Entry& e = at_[static_cast<std::size_t>(terms.coeff_index[static_cast<std::size_t>(p)])];
    first = std::min(first, e.s0);
    last = std::max(last, e.s0 + 1);
  }
  if (last - first + 1 > kSpan) return;  // a term spanning more than a few knots: none here
  Eigen::Matrix<double, 3, 6 * kSpan> J = Eigen::Matrix<double, 3, 6 * kSpan>::Zero();
  for (int p = terms.coeff_begin[static_cast<std::size_t>(t)]; p < terms.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p) {
    const int k = terms.coeff_index[static_cast<std::size_t>(p)];
    if (still[static_cast<std::size_t>(k)]) continue;  // held: it does not move with the knots
    const Entry& e = at_[static_cast<std::size_t>(k)];
    J.middleCols<12>(6 * (e.s0 - first)) += terms.coeff_value[static_cast<std::size_t>(p)] * motion(e.y0, e.f0, e.y1, e.f1);
  }
  // δr gains −δ(R_c e) = −(Ω_c × e) = [e]× Ω_c, Ω_c = Σ_s φ_s(c) ω_s (a held unknown's cell still turns).
  const Eigen::Matrix3d turn = cross_matrix(terms.rest[static_cast<std::size_t>(t)]);
  J.block<3, 3>(0, 6 * (ec.s0 - first)) += ec.f0 * turn;
  J.block<3, 3>(0, 6 * (ec.s0 + 1 - first)) += ec.f1 * turn;
  const int width = 6 * (last - first + 1);
  N.block(6 * first, 6 * first, width, width).noalias() +=
      (sign * terms.weight[static_cast<std::size_t>(t)]) * J.leftCols(width).transpose() * J.leftCols(width);
}

void CoarseSpace::add_tether(int k, double w, Eigen::MatrixXd& N) const {
  if (!(w > 0.0)) return;
  const Entry& e = at_[static_cast<std::size_t>(k)];
  const Eigen::Matrix<double, 3, 12> J = motion(e.y0, e.f0, e.y1, e.f1);
  N.block<12, 12>(6 * e.s0, 6 * e.s0).noalias() += w * J.transpose() * J;
}

Eigen::LDLT<Eigen::MatrixXd> CoarseSpace::factor_holding(const ArapTerms& terms, const std::vector<double>& tether_weight,
                                                          const std::vector<int>& held) const {
  // The held unknowns do not move with the knots: the terms they appear in are priced anew
  // without their motion, and their tether goes.
  Eigen::MatrixXd N = N_;
  std::vector<char> still(at_.size(), 0);
  for (const int k : held) still[static_cast<std::size_t>(k)] = 1;
  std::vector<int> touched;
  for (const int k : held)
    for (int i = terms_of_[static_cast<std::size_t>(k)]; i < terms_of_[static_cast<std::size_t>(k) + 1]; ++i)
      touched.push_back(term_list_[static_cast<std::size_t>(i)]);
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  const std::vector<char> none(at_.size(), 0);
  for (const int t : touched) {
    add_term(terms, t, none, -1.0, N);
    add_term(terms, t, still, 1.0, N);
  }
  for (const int k : held)
    if (!tether_weight.empty()) add_tether(k, -tether_weight[static_cast<std::size_t>(k)], N);
  // A knot nothing prices (no unknown near it) keeps still.
  N.diagonal().array() += 1e-10 * std::max(N.diagonal().cwiseAbs().maxCoeff(), 1.0);
  return Eigen::LDLT<Eigen::MatrixXd>(N);
}

Eigen::VectorXd CoarseSpace::project(const Eigen::MatrixXd& v, const std::vector<char>& skip) const {
  // Jᵀv per knot: (y × v, v) scaled by the hat weight.
  Eigen::VectorXd out = Eigen::VectorXd::Zero(6 * knots_);
  for (std::size_t k = 0; k < at_.size(); ++k) {
    if (skip[k]) continue;
    const Entry& e = at_[k];
    const Eigen::Vector3d vk = v.row(static_cast<Eigen::Index>(k)).transpose();
    out.segment<3>(6 * e.s0) += e.f0 * e.y0.cross(vk);
    out.segment<3>(6 * e.s0 + 3) += e.f0 * vk;
    out.segment<3>(6 * e.s0 + 6) += e.f1 * e.y1.cross(vk);
    out.segment<3>(6 * e.s0 + 9) += e.f1 * vk;
  }
  return out;
}

void CoarseSpace::turn_cells(const Eigen::VectorXd& xi, std::vector<Eigen::Matrix3d>& R) const {
  for (std::size_t c = 0; c < R.size(); ++c) {
    const Entry& e = at_[c];
    // The Cayley rotation of Ω (no trigonometry; equal to exp([Ω]×) to second order).
    const Eigen::Vector3d h = 0.5 * (e.f0 * xi.segment<3>(6 * e.s0) + e.f1 * xi.segment<3>(6 * e.s0 + 6));
    const Eigen::Matrix3d K = cross_matrix(h);
    const Eigen::Matrix3d turn = Eigen::Matrix3d::Identity() + (2.0 / (1.0 + h.squaredNorm())) * (K + K * K);
    R[c] = turn * R[c];
  }
}

}  // namespace evar::deform
