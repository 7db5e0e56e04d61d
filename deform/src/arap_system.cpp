#include "evar/deform/arap_system.hpp"

namespace evar::deform {

void ArapTerms::begin_cell() {
  // cell c spans [cell_begin[c], cell_begin[c + 1]); add_term keeps the last entry at the end.
  ++num_cells;
  cell_begin.push_back(num_terms());
}

namespace {
template <typename Coeffs>
void append_term(ArapTerms& terms, double w, const Coeffs& coeffs, const Eigen::Vector3d& e) {
  terms.weight.push_back(w);
  for (const auto& [k, a] : coeffs) {
    terms.coeff_index.push_back(k);
    terms.coeff_value.push_back(a);
  }
  terms.coeff_begin.push_back(static_cast<int>(terms.coeff_index.size()));
  terms.rest.push_back(e);
  terms.cell_begin.back() = terms.num_terms();
}
}  // namespace

void ArapTerms::add_term(double w, std::initializer_list<std::pair<int, double>> coeffs, const Eigen::Vector3d& e) {
  append_term(*this, w, coeffs, e);
}

void ArapTerms::add_term(double w, const std::vector<std::pair<int, double>>& coeffs, const Eigen::Vector3d& e) {
  append_term(*this, w, coeffs, e);
}

ArapTerms surface_arap_terms(const geometry::Vertices& V,
                             const std::vector<WeightedEdge>& edges, int num_unknowns) {
  const int n = static_cast<int>(V.rows());
  // One-ring adjacency in CSR, so each vertex's half-edges are contiguous.
  std::vector<int> degree(static_cast<std::size_t>(n) + 1, 0);
  for (const auto& e : edges) {
    ++degree[static_cast<std::size_t>(e.i) + 1];
    ++degree[static_cast<std::size_t>(e.j) + 1];
  }
  for (int i = 0; i < n; ++i) degree[static_cast<std::size_t>(i) + 1] += degree[static_cast<std::size_t>(i)];
  std::vector<int> fill(degree.begin(), degree.end() - 1);
  std::vector<std::pair<int, double>> ring(edges.size() * 2);
  for (const auto& e : edges) {
    ring[static_cast<std::size_t>(fill[static_cast<std::size_t>(e.i)]++)] = {e.j, e.w};
    ring[static_cast<std::size_t>(fill[static_cast<std::size_t>(e.j)]++)] = {e.i, e.w};
  }
  ArapTerms terms;
  terms.num_unknowns = num_unknowns;
  terms.weight.reserve(ring.size());
  terms.rest.reserve(ring.size());
  terms.coeff_index.reserve(2 * ring.size());
  terms.coeff_value.reserve(2 * ring.size());
  terms.coeff_begin.reserve(ring.size() + 1);
  for (int i = 0; i < n; ++i) {
    terms.begin_cell();
    for (int r = degree[static_cast<std::size_t>(i)]; r < degree[static_cast<std::size_t>(i) + 1]; ++r) {
      const auto [j, w] = ring[static_cast<std::size_t>(r)];
      terms.add_term(w, {{i, 1.0}, {j, -1.0}}, (V.row(i) - V.row(j)).transpose());
    }
  }
  return terms;
}

Eigen::SparseMatrix<double> assemble_system_matrix(const ArapTerms& terms) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(terms.coeff_index.size() * 3);
  for (int t = 0; t < terms.num_terms(); ++t) {
    const int b = terms.coeff_begin[static_cast<std::size_t>(t)], e = terms.coeff_begin[static_cast<std::size_t>(t) + 1];
    const double w = terms.weight[static_cast<std::size_t>(t)];
    for (int p = b; p < e; ++p)
      for (int q = b; q < e; ++q)
        triplets.emplace_back(terms.coeff_index[static_cast<std::size_t>(p)], terms.coeff_index[static_cast<std::size_t>(q)],
                              w * terms.coeff_value[static_cast<std::size_t>(p)] * terms.coeff_value[static_cast<std::size_t>(q)]);
  }
  Eigen::SparseMatrix<double> A(terms.num_unknowns, terms.num_unknowns);
  A.setFromTriplets(triplets.begin(), triplets.end());
  return A;
}

}  // namespace evar::deform
