#pragma once
// Isotropic remeshing (Botsch & Kobbelt 2004, "A remeshing approach to multiresolution
// modeling"): edges longer than 4/3 L split, shorter than 4/5 L collapsed, flips toward
// valence 6, tangential relaxation, every vertex put back on the input surface. The result
// has near-equilateral triangles of edge about L on the same surface, which is what the
// cotangent weights of ARAP want; a quadric decimation leaves long slivers along a tube
// and can pinch two sheets into a non-manifold edge.
//
// Topology is kept: a collapse must pass the link condition (the two ends share exactly
// the opposite vertices of the edge's faces) and may not fold a face. The rim of an open
// mesh is coarsened along itself only: its vertices stay rim vertices of the input, in
// place, and are not relaxed.
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/geometry/ray_caster.hpp"

namespace evar::deform::detail {

/// The remeshed surface (a new, compact mesh). `surface` must be a valid, manifold mesh and
/// `surface_bvh` a ray caster built over it (vertices are put back on it by its
/// closest-point queries). std::invalid_argument for a
/// non-positive or non-finite edge length.
geometry::TriangleMesh isotropic_remesh(const geometry::TriangleMesh& surface, const geometry::RayCaster& surface_bvh,
                                        double edge_mm, int iterations = 8);

}  // namespace evar::deform::detail
