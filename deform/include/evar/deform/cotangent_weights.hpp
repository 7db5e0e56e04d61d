#pragma once
// Cotangent edge weights w_ij = (cot α_ij + cot β_ij) / 2 (Pinkall & Polthier; used by
// Sorkine & Alexa 2007 for ARAP).
#include <Eigen/Sparse>
#include <vector>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

struct WeightedEdge {
  int i, j;   ///< i < j
  double w;   ///< dimensionless
};

struct CotangentOptions {
  /// Each angle's cotangent is clamped to [-cot_limit, cot_limit]: a sliver's angle near 0
  /// (cot -> inf) or near 180 degrees cannot dominate. 1e3 is an angle of 0.06 degrees.
  double cot_limit = 1e3;
  /// Edge weights below w_floor (obtuse configurations give negative cotangent sums) are
  /// raised to it, so every weight is positive and L is a graph Laplacian: symmetric
  /// positive semidefinite, with only constants in its null space per component.
  double w_floor = 1e-3;
};

/// One entry per undirected edge of `mesh` (#E, sorted by (i, j)). Boundary edges have a
/// single angle. Never NaN: degenerate triangles (zero area) contribute cotangent 0 for
/// their angles (they carry no shape), duplicated vertices must have been welded.
std::vector<WeightedEdge> cotangent_weights(const geometry::TriangleMesh& mesh,
                                            const CotangentOptions& options = {});

/// #V by #V Laplacian L = Σ_edges w_ij (e_i - e_j)(e_i - e_j)^T (positive semidefinite).
Eigen::SparseMatrix<double> cotangent_laplacian(const geometry::TriangleMesh& mesh,
                                                const CotangentOptions& options = {});

}  // namespace evar::deform
