#include <algorithm>
#include <optional>

#include "evar/geometry/polyline.hpp"
#include "vessel_model.hpp"

namespace evar::deform::detail {

void mark_aortic_stump(const VesselModel& carrier, const geometry::Vertices& carrier_deformed,
                       const geometry::TriangleMesh& aorta_rest, const geometry::Vertices& aorta_deformed,
                       std::vector<char>& erased) {
  // The aortic vertices below the bound iliac points: distal of the plane through their
  // centroid (normal: the iliac's initial direction) and inside the deformed iliac, i.e.
  // the part of the aorta the iliac now represents. For an open iliac mesh (no inside) the
  // test is the iliac's top radius around its axis.
  const auto& m = carrier;
  const geometry::Polyline& centerline = m.vessel->centerline;
  const auto arc = geometry::arc_lengths(centerline);
  const Eigen::Vector3d axis = geometry::tangent_at(centerline, arc, 0.0);
  const double cut_radius = m.radius.at(0.0);
  const geometry::TriangleMesh deformed_iliac{carrier_deformed, m.vessel->mesh.mesh.F};
  const std::optional<geometry::RayCaster> inside =
      m.closed ? std::optional<geometry::RayCaster>(std::in_place, deformed_iliac, geometry::RayCaster::BuildQuality::Low)
               : std::nullopt;
  for (Eigen::Index k = 0; k < aorta_rest.V.rows(); ++k) {
    const Eigen::Vector3d q = aorta_rest.V.row(k).transpose() - m.top_centroid;
    const double along = q.dot(axis);
    if (along <= 0.0) continue;
    const bool within = inside ? inside->contains(aorta_deformed.row(k).transpose())
                               : (q - along * axis).norm() < cut_radius;
    if (within) erased[static_cast<std::size_t>(k)] = 1;
  }
}

// Keeps the faces of `faces` that touch no erased vertex of `dv` (vertices keep their
// order) and reports what went and how far the kept vertices moved from `rest`.
void apply_erasure(DeformedVessel& dv, const geometry::Faces& faces, const geometry::Vertices& rest, VesselReport& r) {
  geometry::Faces F(faces.rows(), 3);
  int kept = 0;
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    if (!dv.erased[static_cast<std::size_t>(faces(f, 0))] && !dv.erased[static_cast<std::size_t>(faces(f, 1))] &&
        !dv.erased[static_cast<std::size_t>(faces(f, 2))])
      F.row(kept++) = faces.row(f);
  dv.mesh.F = F.topRows(kept);
  r.erased_faces = static_cast<int>(faces.rows()) - kept;
  r.erased_vertices = static_cast<int>(std::count(dv.erased.begin(), dv.erased.end(), 1));
  r.max_displacement_mm = (dv.mesh.V - rest).rowwise().norm().maxCoeff();
}

}  // namespace evar::deform::detail
