#include "evar/sim/segmentation_phantom.hpp"

#include <vtkCellArray.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkMarchingCubes.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace evar::sim {
namespace {

// A vessel of the label volume: a sweep of spheres along its axis, cut square where it
// ends at the volume's edge of the segmentation (flat), rounded where it ends inside
// (a stub, or the aorta's bottom in the crotch).
struct Tube {
  geometry::Polyline axis;
  std::vector<double> radius_mm;
  bool flat_start = false, flat_end = false;
};

bool inside_segment(const Tube& tube, std::size_t i, const Eigen::Vector3d& p) {
  // A flat end: nothing beyond the plane square to the axis at its end point.
  const std::size_t n = tube.axis.size();
  if (tube.flat_start && (p - tube.axis[0]).dot(tube.axis[1] - tube.axis[0]) < 0.0) return false;
  if (tube.flat_end && (p - tube.axis[n - 1]).dot(tube.axis[n - 1] - tube.axis[n - 2]) > 0.0) return false;
  const Eigen::Vector3d a = tube.axis[i], b = tube.axis[i + 1];
  const double raw = (p - a).dot(b - a) / (b - a).squaredNorm();
  const double t = std::clamp(raw, 0.0, 1.0);
  const double r = (1.0 - t) * tube.radius_mm[i] + t * tube.radius_mm[i + 1];
  return (p - (a + t * (b - a))).squaredNorm() < r * r;
}

bool inside(const Tube& tube, const Eigen::Vector3d& p) {
  for (std::size_t i = 0; i + 1 < tube.axis.size(); ++i)
    if (inside_segment(tube, i, p)) return true;
  return false;
}

Eigen::Vector3d bezier(const std::array<Eigen::Vector3d, 4>& c, double t) {
  const double u = 1.0 - t;
  return u * u * u * c[0] + 3 * u * u * t * c[1] + 3 * u * t * t * c[2] + t * t * t * c[3];
}

// Where `stub`'s axis leaves `parent`: the first axis point outside it, moved back onto
// its wall by bisection.
Eigen::Vector3d ostium(const Tube& parent, const Tube& stub) {
  const Eigen::Vector3d a = stub.axis.front(), b = stub.axis.back();
  double lo = 0.0, hi = 1.0;
  for (double t = 0.0; t <= 1.0; t += 0.01)
    if (!inside(parent, a + t * (b - a))) {
      hi = t;
      break;
    } else {
      lo = t;
    }
  for (int k = 0; k < 40; ++k) {
    const double mid = 0.5 * (lo + hi);
    (inside(parent, a + mid * (b - a)) ? lo : hi) = mid;
  }
  return a + hi * (b - a);
}

Tube straight(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius_mm) {
  Tube t;
  const int n = std::max(2, static_cast<int>(std::ceil((to - from).norm() / 2.0)) + 1);
  for (int k = 0; k < n; ++k) {
    t.axis.push_back(from + (to - from) * (static_cast<double>(k) / (n - 1)));
    t.radius_mm.push_back(radius_mm);
  }
  return t;
}

}  // namespace

SegmentationPhantom make_segmentation_phantom(const SegmentationPhantomOptions& options) {
  if (!(options.spacing_mm.minCoeff() > 0.1 && options.spacing_mm.maxCoeff() <= 5.0))
    throw std::invalid_argument("segmentation phantom: voxel spacing must lie in (0.1, 5] mm");
  if (!(options.lowest_z_mm >= -100.0 && options.highest_z_mm <= 133.0 && options.lowest_z_mm < 0.0 &&
        options.highest_z_mm > 100.0))
    throw std::invalid_argument("segmentation phantom: its extent must keep the renal arteries and the bifurcation "
                                "(lowest_z_mm in [-100, 0), highest_z_mm in (100, 133])");
  SegmentationPhantom out;

  // The aorta, an aneurysm of 28 mm across below the renal arteries, bowing forward a little.
  Tube aorta;
  aorta.flat_start = true;
  for (double z = 130.0; z >= 10.0 - 1e-9; z -= 2.0) {
    aorta.axis.push_back({0.0, -3.0 * std::sin(M_PI * (130.0 - z) / 120.0), z});
    aorta.radius_mm.push_back(10.0 + 4.0 * std::exp(-std::pow((z - 60.0) / 22.0, 2)));
  }
  // The iliacs from inside the aorta's bottom, out and back and down, narrowing.
  std::array<Tube, 2> iliacs;
  std::array<std::array<Eigen::Vector3d, 4>, 2> iliac_curve;
  for (int side = 0; side < 2; ++side) {
    const double s = side == 0 ? -1.0 : 1.0;  // right is -x in LPS
    iliac_curve[static_cast<std::size_t>(side)] = {Eigen::Vector3d(0, 0, 14), Eigen::Vector3d(s * 10, 0, -12),
                                                   Eigen::Vector3d(s * 28, 8, -45), Eigen::Vector3d(s * 32, 12, -95)};
    Tube& t = iliacs[static_cast<std::size_t>(side)];
    t.flat_end = true;
    for (int k = 0; k <= 60; ++k) {
      t.axis.push_back(bezier(iliac_curve[static_cast<std::size_t>(side)], k / 60.0));
      t.radius_mm.push_back(6.0 - 1.5 * k / 60.0);
    }
  }
  std::vector<Tube> tubes{aorta, iliacs[0], iliacs[1]};
  out.bifurcation = aorta.axis.back();

  // Truth paths: the aorta down to the iliacs' start, then each iliac.
  geometry::Polyline trunk;
  for (const auto& p : aorta.axis)
    if (p.z() > iliacs[0].axis.front().z()) trunk.push_back(p);
  for (const auto& iliac : iliacs) {
    geometry::Polyline path = trunk;
    path.insert(path.end(), iliac.axis.begin(), iliac.axis.end());
    out.paths.push_back(std::move(path));
  }

  if (options.side_branches) {
    // Renal stubs at z = 95, 3 mm in radius; internal iliac stubs from each iliac's middle,
    // back, in and down, 2.5 mm.
    const Eigen::Vector3d renal_origin(0.0, -3.0 * std::sin(M_PI * 35.0 / 120.0), 95.0);
    const char* renal_names[2] = {"renal_right", "renal_left"};
    const char* internal_names[2] = {"internal_iliac_right", "internal_iliac_left"};
    for (int side = 0; side < 2; ++side) {
      const double s = side == 0 ? -1.0 : 1.0;
      const Tube renal = straight(renal_origin, renal_origin + Eigen::Vector3d(s * 30.0, 4.0, 2.0), 3.0);
      out.ostia.push_back({renal_names[side], ostium(aorta, renal)});
      geometry::Polyline path;
      for (const auto& p : aorta.axis)
        if (p.z() > renal_origin.z()) path.push_back(p);
      path.insert(path.end(), renal.axis.begin(), renal.axis.end());
      out.paths.push_back(std::move(path));
      tubes.push_back(renal);
    }
    for (int side = 0; side < 2; ++side) {
      const double s = side == 0 ? -1.0 : 1.0;
      const Eigen::Vector3d from = bezier(iliac_curve[static_cast<std::size_t>(side)], 0.55);
      const Tube internal = straight(from, from + 24.0 * Eigen::Vector3d(-s * 0.35, 0.75, -0.55).normalized(), 2.5);
      out.ostia.push_back({internal_names[side], ostium(iliacs[static_cast<std::size_t>(side)], internal)});
      geometry::Polyline path = trunk;
      const auto& parent = iliacs[static_cast<std::size_t>(side)].axis;
      path.insert(path.end(), parent.begin(), parent.begin() + 33);  // up to t = 0.55
      path.insert(path.end(), internal.axis.begin(), internal.axis.end());
      out.paths.push_back(std::move(path));
      tubes.push_back(internal);
    }
  }

  // The label volume over the extent, with two voxels of background round it.
  const Eigen::Vector3d& h = options.spacing_mm;
  const Eigen::Vector3d lo = Eigen::Vector3d(-50.0, -25.0, options.lowest_z_mm) - 2.0 * h;
  const Eigen::Vector3d hi = Eigen::Vector3d(50.0, 35.0, options.highest_z_mm) + 2.0 * h;
  Eigen::Vector3i dims;
  for (int a = 0; a < 3; ++a) dims[a] = static_cast<int>(std::ceil((hi[a] - lo[a]) / h[a])) + 1;
  vtkNew<vtkImageData> volume;
  volume->SetDimensions(dims.x(), dims.y(), dims.z());
  volume->SetSpacing(h.x(), h.y(), h.z());
  volume->SetOrigin(lo.x(), lo.y(), lo.z());
  std::vector<unsigned char> label(static_cast<std::size_t>(dims.prod()), 0);
  for (const auto& tube : tubes)
    for (std::size_t i = 0; i + 1 < tube.axis.size(); ++i) {
      const double r = std::max(tube.radius_mm[i], tube.radius_mm[i + 1]);
      const Eigen::Vector3d bmin = tube.axis[i].cwiseMin(tube.axis[i + 1]).array() - r;
      const Eigen::Vector3d bmax = tube.axis[i].cwiseMax(tube.axis[i + 1]).array() + r;
      Eigen::Vector3i from, to;
      for (int a = 0; a < 3; ++a) {
        from[a] = std::max(2, static_cast<int>(std::floor((bmin[a] - lo[a]) / h[a])));
        to[a] = std::min(dims[a] - 3, static_cast<int>(std::ceil((bmax[a] - lo[a]) / h[a])));
      }
      for (int k = from.z(); k <= to.z(); ++k)
        for (int j = from.y(); j <= to.y(); ++j)
          for (int i2 = from.x(); i2 <= to.x(); ++i2) {
            unsigned char& v = label[(static_cast<std::size_t>(k) * static_cast<std::size_t>(dims.y()) + static_cast<std::size_t>(j)) *
                                         static_cast<std::size_t>(dims.x()) + static_cast<std::size_t>(i2)];
            if (!v && inside_segment(tube, i, lo + Eigen::Vector3d(i2 * h.x(), j * h.y(), k * h.z()))) v = 1;
          }
    }

  // What marching cubes contours: the label with each voxel's value pulled up to 45 % of
  // the way toward the other side, as an intensity threshold on a noisy image leaves it,
  // so vertices land anywhere along the voxel edges (slivers), not at their middles.
  volume->AllocateScalars(VTK_FLOAT, 1);
  auto* field = static_cast<float*>(volume->GetScalarPointer());
  std::uint32_t state = 0x9e3779b9u;
  for (std::size_t v = 0; v < label.size(); ++v) {
    state ^= state << 13, state ^= state >> 17, state ^= state << 5;  // xorshift32: the same volume every run
    const float pull = 0.45f * static_cast<float>(state >> 8) / static_cast<float>(1u << 24);
    field[v] = label[v] ? 1.0f - pull : pull;
  }

  vtkNew<vtkMarchingCubes> cubes;
  cubes->SetInputData(volume);
  cubes->SetValue(0, 0.5);
  cubes->ComputeNormalsOff();
  cubes->ComputeGradientsOff();
  cubes->ComputeScalarsOff();
  cubes->Update();
  vtkPolyData* surface = cubes->GetOutput();
  if (surface->GetNumberOfPoints() == 0) throw std::runtime_error("segmentation phantom: marching cubes made no surface");

  switch (options.frame) {
    case PhantomFrame::Lps: out.axes = "LPS"; break;
    case PhantomFrame::Ras:
      out.axes = "RAS";
      out.to_lps = Eigen::Vector3d(-1, -1, 1).asDiagonal();
      break;
    case PhantomFrame::Image:
      out.axes = "LIP";
      out.to_lps << 1, 0, 0,  //
          0, 0, 1,            //
          0, -1, 0;           // file y to the feet (-z), file z to the back (+y)
      break;
  }
  const Eigen::Matrix3d from_lps = out.to_lps.transpose();
  auto& mesh = out.surface;
  mesh.V.resize(surface->GetNumberOfPoints(), 3);
  for (vtkIdType i = 0; i < surface->GetNumberOfPoints(); ++i) {
    double p[3];
    surface->GetPoint(i, p);
    mesh.V.row(i) = (from_lps * Eigen::Vector3d(p[0], p[1], p[2])).transpose();
  }
  mesh.F.resize(surface->GetNumberOfPolys(), 3);
  vtkNew<vtkIdList> ids;
  vtkCellArray* polys = surface->GetPolys();
  Eigen::Index f = 0;
  for (polys->InitTraversal(); polys->GetNextCell(ids);)
    if (ids->GetNumberOfIds() == 3)
      mesh.F.row(f++) << static_cast<int>(ids->GetId(0)), static_cast<int>(ids->GetId(1)), static_cast<int>(ids->GetId(2));
  mesh.F.conservativeResize(f, 3);
  return out;
}

}  // namespace evar::sim
