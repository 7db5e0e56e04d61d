#pragma once
// A triangle surface mesh in patient LPS millimetres.
#include <Eigen/Core>
#include <string_view>

namespace evar::geometry {

/// #V by 3 vertex positions (mm), one row per vertex.
using Vertices = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// #F by 3 vertex indices (0-based), one row per triangle.
using Faces = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct TriangleMesh {
  Vertices V;  ///< #V by 3, mm
  Faces F;     ///< #F by 3
};

/// Checks what the deformation relies on and throws InputError naming `source` and the
/// offending vertex/face/edge: at least one face, finite coordinates, indices in range,
/// no triangle with a repeated index, no edge shared by more than two faces.
void validate_mesh(const TriangleMesh& mesh, std::string_view source);

/// Mean edge length (mm) over all face edges; 0 for a mesh without faces.
double mean_edge_length(const TriangleMesh& mesh);

}  // namespace evar::geometry
