#include "evar/geometry/centerline_file.hpp"

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkType.h>

#include <cmath>
#include <string>

#include "evar/base/input_file.hpp"
#include "evar/base/quantity_text.hpp"
#include "mesh_formats.hpp"
#include "vtk_xml.hpp"

namespace evar::geometry {

CenterlineFile read_centerline_file(const std::filesystem::path& path) {
  const std::string bytes = base::read_input_file(path, base::kMeshLimit);
  const detail::PolyDataHandle data = detail::parse_vtp(path, bytes);
  CenterlineFile out;
  out.space = detail::vtp_declared_space(path, *data);
  const double flip = out.space == MeshSpace::Ras ? -1.0 : 1.0;
  vtkCellArray* lines = data->GetLines();
  if (!lines || lines->GetNumberOfCells() == 0)
    detail::fail(path, "holds no lines: a centerline file has one polyline per centerline (VMTK's vmtkcenterlines "
                       "writes them); is it a surface?");
  const vtkIdType n = data->GetNumberOfPoints();
  vtkDataArray* radius = data->GetPointData() ? data->GetPointData()->GetArray(kVmtkRadiusArray) : nullptr;
  if (radius && (radius->GetNumberOfComponents() != 1 || radius->GetNumberOfTuples() != n))
    detail::fail(path, std::string("point array ") + kVmtkRadiusArray + ": expected one value per point (" +
                           std::to_string(n) + "), found " + std::to_string(radius->GetNumberOfTuples()) + " of " +
                           std::to_string(radius->GetNumberOfComponents()));
  vtkCellData* cells = data->GetCellData();
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < lines->GetNumberOfCells(); ++c) {
    lines->GetCellAtId(c, ids);
    CenterlineCurve curve;
    for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k) {
      const vtkIdType id = ids->GetId(k);
      if (id < 0 || id >= n)
        detail::fail(path, "Lines: cell " + std::to_string(c) + " has point index " + std::to_string(id) +
                               " but the file has " + std::to_string(n) + " points");
      double p[3];
      data->GetPoint(id, p);
      const Eigen::Vector3d x(flip * p[0], flip * p[1], p[2]);
      if (!x.allFinite()) detail::fail(path, "point " + std::to_string(id) + " is not finite");
      curve.points.push_back(x);
      if (radius) {
        const double r = radius->GetTuple1(id);
        if (!std::isfinite(r) || r < 0.0)
          detail::fail(path, std::string("point array ") + kVmtkRadiusArray + ": point " + std::to_string(id) +
                                 " has radius " + base::quantity_text(r, "mm") + "; a radius is a finite length >= 0");
        curve.radius_mm.push_back(r);
      }
    }
    if (cells)
      for (int a = 0; a < cells->GetNumberOfArrays(); ++a) {
        vtkDataArray* array = cells->GetArray(a);
        if (!array || !array->GetName() || array->GetNumberOfComponents() != 1 || !(array->GetDataType() == VTK_INT || array->GetDataType() == VTK_LONG || array->GetDataType() == VTK_LONG_LONG || array->GetDataType() == VTK_ID_TYPE || array->GetDataType() == VTK_SHORT || array->GetDataType() == VTK_CHAR || array->GetDataType() == VTK_SIGNED_CHAR || array->GetDataType() == VTK_UNSIGNED_CHAR || array->GetDataType() == VTK_UNSIGNED_INT)) continue;
        if (array->GetNumberOfTuples() <= c) continue;
        curve.cell_values[array->GetName()] = static_cast<long long>(array->GetTuple1(c));
      }
    out.curves.push_back(std::move(curve));
  }
  return out;
}

}  // namespace evar::geometry
