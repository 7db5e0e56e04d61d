#include "vtk_xml.hpp"

#include <vtkCallbackCommand.h>
#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkIdList.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include <cmath>
#include <mutex>
#include <string>
#include <vector>

#include "evar/base/atomic_file.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry::detail {

void VtkPolyDataDeleter::operator()(vtkPolyData* p) const {
  if (p) p->Delete();
}

namespace {

// VTK prints what its objects report (through the output window) unless someone listens
// to the object; helper objects inside a reader (its XML parser) report on their own. This
// window keeps every such text for the thread that is reading, and prints nothing.
class CapturingOutputWindow : public vtkOutputWindow {
 public:
  static CapturingOutputWindow* New();
  vtkTypeMacro(CapturingOutputWindow, vtkOutputWindow)
  void DisplayText(const char* text) override {
    if (sink && text && sink->empty()) *sink = text;
  }
  static thread_local std::string* sink;  // the text of the first report while reading, or null
};
vtkStandardNewMacro(CapturingOutputWindow)
thread_local std::string* CapturingOutputWindow::sink = nullptr;

// VTK's texts say where in VTK's sources, then "vtkClass (0x...): " and the message.
std::string vtk_message(std::string text) {
  if (const auto at = text.find("): "); at != std::string::npos) text = text.substr(at + 3);
  for (char& c : text)
    if (c == '\n' || c == '\r') c = ' ';
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

// What VTK reports while this lives on this thread: the first error the object raises
// (an ErrorEvent) or, failing that, the first text any VTK object would have printed.
class VtkMessages {
 public:
  explicit VtkMessages(vtkObject* source) {
    static std::once_flag installed;
    std::call_once(installed, [] {
      vtkNew<CapturingOutputWindow> window;
      vtkOutputWindow::SetInstance(window);
      vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);  // its copy of the same reports
    });
    CapturingOutputWindow::sink = &printed_;
    callback_->SetClientData(this);
    callback_->SetCallback([](vtkObject*, unsigned long, void* self, void* text) {
      auto* me = static_cast<VtkMessages*>(self);
      if (me->error_.empty()) me->error_ = vtk_message(text ? static_cast<const char*>(text) : "");
    });
    source->AddObserver(vtkCommand::ErrorEvent, callback_);
  }
  ~VtkMessages() { CapturingOutputWindow::sink = nullptr; }
  VtkMessages(const VtkMessages&) = delete;
  VtkMessages& operator=(const VtkMessages&) = delete;
  /// The object's first error; else the first printed error of another; "" when none.
  std::string error() const {
    if (!error_.empty()) return error_;
    return printed_.find("ERR") != std::string::npos || printed_.find("rror") != std::string::npos
               ? vtk_message(printed_)
               : std::string();
  }

 private:
  vtkNew<vtkCallbackCommand> callback_;
  std::string error_, printed_;
};

// The ids of cell `c` of `cells`, which VTK owns.
std::vector<vtkIdType> cell_ids(vtkCellArray& cells, vtkIdType c, vtkIdList& scratch) {
  cells.GetCellAtId(c, &scratch);
  std::vector<vtkIdType> ids(static_cast<std::size_t>(scratch.GetNumberOfIds()));
  for (vtkIdType k = 0; k < scratch.GetNumberOfIds(); ++k) ids[static_cast<std::size_t>(k)] = scratch.GetId(k);
  return ids;
}

}  // namespace

PolyDataHandle parse_vtp(const std::filesystem::path& path, std::string_view bytes) {
  if (bytes.find("<VTKFile") == std::string_view::npos)
    fail(path, "is not a VTK XML file (no <VTKFile> element); a .vtp must be VTK XML PolyData");
  vtkNew<vtkXMLPolyDataReader> reader;
  const VtkMessages messages(reader);
  reader->ReadFromInputStringOn();
  reader->SetInputString(std::string(bytes));
  reader->Update();
  if (!messages.error().empty()) fail(path, "VTK's XML reader: " + messages.error());
  vtkPolyData* out = reader->GetOutput();
  if (!out) fail(path, "VTK's XML reader returned no polydata");
  PolyDataHandle data(vtkPolyData::New());
  data->DeepCopy(out);
  return data;
}

MeshSpace vtp_declared_space(const std::filesystem::path& path, vtkPolyData& data) {
  vtkFieldData* fields = data.GetFieldData();
  if (!fields) return MeshSpace::Undeclared;
  vtkAbstractArray* array = fields->GetAbstractArray("SPACE");
  if (!array) return MeshSpace::Undeclared;
  auto* strings = vtkStringArray::SafeDownCast(array);
  if (!strings || strings->GetNumberOfValues() != 1)
    fail(path, "field data SPACE: expected one string, LPS or RAS, as 3D Slicer writes it");
  const std::string value = strings->GetValue(0);
  if (value == "LPS") return MeshSpace::Lps;
  if (value == "RAS") return MeshSpace::Ras;
  fail(path, "field data SPACE: is " + detail::quoted(value) + "; expected LPS or RAS");
}

LoadedMesh read_vtp(const std::filesystem::path& path, std::string_view bytes) {
  const PolyDataHandle data = parse_vtp(path, bytes);
  LoadedMesh out;
  out.format = MeshFormat::Vtp;
  out.space = vtp_declared_space(path, *data);
  const vtkIdType n = data->GetNumberOfPoints();
  out.mesh.V.resize(n, 3);
  for (vtkIdType i = 0; i < n; ++i) {
    double p[3];
    data->GetPoint(i, p);
    for (int k = 0; k < 3; ++k) out.mesh.V(i, k) = p[k];
  }
  std::vector<Eigen::Vector3i> triangles;
  vtkNew<vtkIdList> scratch;
  const auto check = [&](const char* section, vtkIdType cell, const std::vector<vtkIdType>& ids) {
    for (const vtkIdType id : ids)
      if (id < 0 || id >= n)
        fail(path, std::string(section) + ": cell " + std::to_string(cell) + " has point index " + std::to_string(id) +
                       " but the file has " + std::to_string(n) + " points");
  };
  if (vtkCellArray* polys = data->GetPolys())
    for (vtkIdType c = 0; c < polys->GetNumberOfCells(); ++c) {
      const auto ids = cell_ids(*polys, c, *scratch);
      check("Polys", c, ids);
      for (std::size_t k = 1; k + 1 < ids.size(); ++k)
        triangles.emplace_back(static_cast<int>(ids[0]), static_cast<int>(ids[k]), static_cast<int>(ids[k + 1]));
    }
  if (vtkCellArray* strips = data->GetStrips())
    for (vtkIdType c = 0; c < strips->GetNumberOfCells(); ++c) {
      const auto ids = cell_ids(*strips, c, *scratch);
      check("Strips", c, ids);
      for (std::size_t k = 0; k + 2 < ids.size(); ++k) {
        Eigen::Vector3i t(static_cast<int>(ids[k]), static_cast<int>(ids[k + 1]), static_cast<int>(ids[k + 2]));
        if (k % 2 == 1) std::swap(t[1], t[2]);  // every second one turned so all face the same way
        if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) triangles.push_back(t);
      }
    }
  if (triangles.empty() && data->GetNumberOfLines() > 0)
    fail(path, "holds " + std::to_string(data->GetNumberOfLines()) +
                   " lines and no surface: it looks like a centerline file (give it where centerlines are asked for)");
  out.mesh.F.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t f = 0; f < triangles.size(); ++f) out.mesh.F.row(static_cast<Eigen::Index>(f)) = triangles[f].transpose();
  return out;
}

void write_vtp(const std::filesystem::path& path, const TriangleMesh& mesh, MeshSpace space) {
  check_indices_for_writing(mesh, path);
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(mesh.V.rows());
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) points->SetPoint(i, mesh.V(i, 0), mesh.V(i, 1), mesh.V(i, 2));
  vtkNew<vtkCellArray> polys;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const vtkIdType ids[3] = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
    polys->InsertNextCell(3, ids);
  }
  vtkNew<vtkPolyData> data;
  data->SetPoints(points);
  data->SetPolys(polys);
  vtkNew<vtkStringArray> tag;
  tag->SetName("SPACE");
  tag->InsertNextValue(space == MeshSpace::Ras ? "RAS" : "LPS");
  data->GetFieldData()->AddArray(tag);

  vtkNew<vtkXMLPolyDataWriter> writer;
  const VtkMessages messages(writer);
  writer->SetInputData(data);
  writer->SetDataModeToAppended();
  writer->SetCompressorTypeToZLib();
  writer->WriteToOutputStringOn();
  if (!writer->Write() || !messages.error().empty())
    throw std::runtime_error(path.string() + ": VTK's XML writer failed: " + messages.error());
  base::write_file_atomically(path, writer->GetOutputString());
}

}  // namespace evar::geometry::detail
