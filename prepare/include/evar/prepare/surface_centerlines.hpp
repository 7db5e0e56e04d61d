#pragma once
// Centerlines of an aorto-iliac surface from the surface alone, for a segmentation that
// comes without them: the surface's mean-curvature-flow skeleton (CGAL), its ends found,
// the aortic inlet told from the outlets by the lumen's width, each end run on to the
// surface's cap or opening, radii from the distance to the nearest wall. The result reads
// as VMTK's centerline paths do: one per outlet, each from the inlet.
#include <string>
#include <vector>

#include "evar/geometry/centerline_file.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::prepare {

struct SurfaceCenterlines {
  std::vector<geometry::CenterlineCurve> paths;  ///< inlet to each outlet, radius_mm per point
  int skeleton_points = 0;
  int openings_closed = 0;  ///< holes of an open surface closed for the skeleton only
  int spurs_dropped = 0;    ///< skeleton ends that never left their parent's lumen
  double skeleton_ms = 0.0;
};

/// `surface` in LPS, one connected two-manifold surface (closed, or open at its vessel
/// ends), `walls` built over it. base::InputError naming `source` when the surface cannot
/// be skeletonised (not manifold, not consistently wound) or its skeleton has fewer than
/// three ends (not an aorto-iliac bifurcation), each with what to do instead.
SurfaceCenterlines centerlines_from_surface(const geometry::TriangleMesh& surface, const geometry::RayCaster& walls,
                                            const std::string& source);

}  // namespace evar::prepare
