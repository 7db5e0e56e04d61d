#pragma once
// The weak tether of a vessel's surface to its registered (preoperative) pose:
// energy Σ_i (A_i / ℓ²) |v'_i − v_i|², A_i the barycentric vertex area (docs/DEFORMATION.md).
#include "evar/deform/arap_solver.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

/// Tether for `unknowns` unknowns whose first #V are the mesh's vertices (the rest, e.g.
/// skeleton centres, get weight 0). length_mm <= 0 gives an empty tether (off).
ArapTether registration_tether(const geometry::TriangleMesh& mesh, int unknowns, double length_mm);

}  // namespace evar::deform
