#pragma once
// Which side of a vessel wall a point lies on, for surfaces open at their ends (vessels cut
// off where the segmentation stopped) as well as closed ones: the sign of (p − q)·n at the
// closest point q, with n the angle-weighted pseudonormal of the feature holding q (face,
// edge or vertex; Bærentzen & Aanæs, IEEE TVCG 2005), which gives the right sign on a
// closed surface wherever q lies. At an open end the wall stops and the sign means
// little there: where q is on the rim of an opening and p lies past the rim (p − q points
// out of the opening, m, the direction in the wall away from it, across the rim), p is
// beside the wall, outside, only when it is more out through the wall (along n) than out
// past the rim (along m); otherwise it is beyond the opening, where the surface cannot
// tell. Caps (faces that close a model where its segmentation stopped) may be marked: they
// count for inside, so the side is exact right up to them, but a point outside whose
// closest feature touches one is beyond an opening, as it would be with the cap cut away.
#include <Eigen/Core>
#include <limits>
#include <optional>
#include <vector>

#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry {

enum class Side { Inside, Outside, BeyondOpening };

struct SidedPoint {
  Side side = Side::BeyondOpening;
  double distance_mm = 0.0;  ///< to the closest point of the surface
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();
};

class SurfaceSide {
 public:
  /// Faces must wind consistently with outward normals (as every vessel mesh of a scene
  /// does; scene loading checks it). Vertices no face uses are ignored.
  explicit SurfaceSide(const TriangleMesh& mesh, RayCaster::BuildQuality quality = RayCaster::BuildQuality::Low);
  /// `cap_faces`: one flag per face, non-zero for a cap (none marked when empty).
  SurfaceSide(const TriangleMesh& mesh, std::vector<char> cap_faces,
              RayCaster::BuildQuality quality = RayCaster::BuildQuality::Low);

  /// The side of `p` (BeyondOpening, infinitely far, for a mesh without faces).
  /// `expected_distance_mm`: a bound the closest point is likely within (e.g. the previous
  /// point's distance plus the step to this one), which saves most of the search when it
  /// holds; the answer is the same either way.
  SidedPoint classify(const Eigen::Vector3d& p,
                      double expected_distance_mm = std::numeric_limits<double>::infinity()) const;

  /// An opening of the surface (a loop of boundary edges), as the slab it spans: centre,
  /// unit normal of its best-fit plane, radius (farthest loop vertex from the centre) and
  /// half thickness (farthest loop vertex from the plane).
  struct Opening {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::UnitZ();
    double radius_mm = 0.0, half_thickness_mm = 0.0;
  };
  const std::vector<Opening>& openings() const { return openings_; }

  /// For a point `p` classified Inside at `distance_mm` from the surface: the radius of a
  /// ball round it that holds no surface and reaches no opening, so every point in it is
  /// inside as well (nine tenths of the distance, less where an opening is nearer).
  double inside_ball_radius_mm(const Eigen::Vector3d& p, double distance_mm) const;

 private:
  // The pseudonormal at a feature, for one on a rim the direction m out past it (zero
  // elsewhere), and whether a cap face holds it.
  struct FeatureNormal {
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    Eigen::Vector3d rim_out = Eigen::Vector3d::Zero();
    bool on_cap = false;
  };
  FeatureNormal at_edge(int face, int i, int j) const;
  FeatureNormal at_vertex(int v) const;
  // m for the rim edge (i, j) of `face`: from its third corner across the edge, square to it.
  Eigen::Vector3d rim_out(int face, int i, int j) const;

  const TriangleMesh& mesh() const { return caster_->mesh(); }

  std::optional<RayCaster> caster_;  // none for a mesh without faces; holds the mesh
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> face_normals_;  // unit (zero for a sliver)
  // The faces around each vertex: faces_of_[first_face_[v] .. first_face_[v + 1]).
  std::vector<int> first_face_, faces_of_;
  std::vector<char> cap_faces_;  // empty, or one flag per face
  std::vector<Opening> openings_;

  bool is_cap(int face) const { return !cap_faces_.empty() && cap_faces_[static_cast<std::size_t>(face)] != 0; }
};

}  // namespace evar::geometry
