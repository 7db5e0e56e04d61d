#pragma once
// A triangle surface mesh in patient LPS millimetres.
#include <Eigen/Core>
#include <string_view>

namespace evar::geometry {

/// Points, one row each (x y z, mm): a mesh's vertices, and every other set of points the
/// deformation solves for (skeleton centres, targets, iterates). The one points matrix type.
using Vertices = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// #F by 3 vertex indices (0-based), one row per triangle.
using Faces = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct TriangleMesh {
  Vertices V;  ///< #V by 3, mm
  Faces F;     ///< #F by 3
};

/// Largest coordinate magnitude accepted from files (mm): 100 m. Beyond it a file has the
/// wrong units or garbage, and squared lengths would overflow downstream.
inline constexpr double kMaxCoordinateMm = 1e5;

/// Checks what the deformation relies on and throws InputError naming `source` and the
/// offending vertex/face/edge: at least one face, finite coordinates within
/// kMaxCoordinateMm, indices in range,
/// no triangle with a repeated index, no edge shared by more than two faces.
void validate_mesh(const TriangleMesh& mesh, std::string_view source);

/// True when every edge is shared by exactly two faces (a closed surface, which has an
/// inside for ray-parity tests).
bool is_closed(const TriangleMesh& mesh);

/// Volume (mm^3) enclosed by a closed triangle mesh: the divergence-theorem sum of the
/// signed tetrahedra (origin, a, b, c) / 6. Positive when the faces point outward; only
/// meaningful for a closed mesh (an open mesh gives a value that depends on the origin).
double enclosed_volume(const TriangleMesh& mesh);

/// Median edge length (mm) over all face edges (robust to a few stray vertices); 0 for a
/// mesh without faces.
double median_edge_length(const TriangleMesh& mesh);

/// Mean edge length (mm) over all face edges; 0 for a mesh without faces.
double mean_edge_length(const TriangleMesh& mesh);

}  // namespace evar::geometry
