#include "render/mesh_io.hpp"

#include "core/error.hpp"

#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkTypeInt32Array.h>
#include <vtkTypeInt64Array.h>
#include <vtkXMLPolyDataWriter.h>

#include <unistd.h>

#include <limits>
#include <type_traits>

namespace vmsim::render {

void write_vtp(const std::filesystem::path& file, const core::TriangleMesh& mesh, int zlib_level) {
  if (zlib_level < 1 || zlib_level > 9)
    throw core::Error(file.string() + ": zlib compression level " + std::to_string(zlib_level) + " is not in 1..9");
  for (const auto& [name, values] : mesh.point_data)
    if (values.size() != mesh.vertices_mm.rows())
      throw core::Error(file.string() + ": point data \"" + name + "\" does not have one value per vertex");
  const vtkIdType nv = mesh.vertices_mm.rows(), nt = mesh.triangles.rows();
  // VTK's arrays over the mesh's own storage, not copies (save = 1: VTK neither frees nor writes them; the writer only
  // reads): the vertices are row-major x y z as vtkPoints holds them, the triangles row-major int as 32-bit cells.
  vtkNew<vtkDoubleArray> xyz;
  xyz->SetNumberOfComponents(3);
  xyz->SetArray(const_cast<double*>(mesh.vertices_mm.data()), 3 * nv, 1);
  vtkNew<vtkPoints> pts;
  pts->SetData(xyz);
  vtkNew<vtkCellArray> polys;
  static_assert(std::is_same_v<vtkTypeInt32, int>);
  if (3 * nt <= std::numeric_limits<vtkTypeInt32>::max()) {
    vtkNew<vtkTypeInt32Array> offsets, connectivity;
    offsets->SetNumberOfValues(nt + 1);
    for (vtkIdType t = 0; t <= nt; ++t) offsets->SetValue(t, static_cast<vtkTypeInt32>(3 * t));
    connectivity->SetArray(const_cast<int*>(mesh.triangles.data()), 3 * nt, 1);
    polys->SetData(offsets, connectivity);
  } else {  // over 715 M triangles: offsets past 2^31 need 64-bit cells
    vtkNew<vtkTypeInt64Array> offsets, connectivity;
    offsets->SetNumberOfValues(nt + 1);
    for (vtkIdType t = 0; t <= nt; ++t) offsets->SetValue(t, 3 * t);
    connectivity->SetNumberOfValues(3 * nt);
    for (vtkIdType k = 0; k < 3 * nt; ++k) connectivity->SetValue(k, mesh.triangles.data()[k]);
    polys->SetData(offsets, connectivity);
  }
  vtkNew<vtkPolyData> pd;
  pd->SetPoints(pts);
  pd->SetPolys(polys);
  for (const auto& [name, values] : mesh.point_data) {
    vtkNew<vtkDoubleArray> a;
    a->SetName(name.c_str());
    a->SetArray(const_cast<double*>(values.data()), nv, 1);
    pd->GetPointData()->AddArray(a);
    if (!pd->GetPointData()->GetScalars()) pd->GetPointData()->SetActiveScalars(name.c_str());
  }
  std::filesystem::path tmp = file;
  tmp += ".tmp" + std::to_string(::getpid());
  vtkNew<vtkXMLPolyDataWriter> w;
  w->SetFileName(tmp.string().c_str());
  w->SetInputData(pd);
  // Appended raw binary (VTK XML's documented alternative to base64 inside the XML; ParaView and VTK read both):
  // a quarter smaller and no base64 pass.
  w->SetDataModeToAppended();
  w->EncodeAppendedDataOff();
  w->SetCompressorTypeToZLib();
  w->SetCompressionLevel(zlib_level);
  if (w->Write() != 1) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw core::Error(file.string() + ": VTK could not write the mesh");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) throw core::Error(file.string() + ": cannot move the finished file into place: " + ec.message());
}

}  // namespace vmsim::render
