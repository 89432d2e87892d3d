#include "render/mesh_io.hpp"

#include "core/error.hpp"

#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkXMLPolyDataWriter.h>

#include <unistd.h>

namespace vmsim::render {

void write_vtp(const std::filesystem::path& file, const core::TriangleMesh& mesh, int zlib_level) {
  if (zlib_level < 1 || zlib_level > 9)
    throw core::Error(file.string() + ": zlib compression level " + std::to_string(zlib_level) + " is not in 1..9");
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(mesh.vertices_mm.rows());
  for (Eigen::Index i = 0; i < mesh.vertices_mm.rows(); ++i)
    pts->SetPoint(i, mesh.vertices_mm(i, 0), mesh.vertices_mm(i, 1), mesh.vertices_mm(i, 2));
  vtkNew<vtkCellArray> polys;
  polys->AllocateExact(mesh.triangles.rows(), 3 * mesh.triangles.rows());
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    const vtkIdType ids[3] = {mesh.triangles(t, 0), mesh.triangles(t, 1), mesh.triangles(t, 2)};
    polys->InsertNextCell(3, ids);
  }
  vtkNew<vtkPolyData> pd;
  pd->SetPoints(pts);
  pd->SetPolys(polys);
  for (const auto& [name, values] : mesh.point_data) {
    if (values.size() != mesh.vertices_mm.rows())
      throw core::Error(file.string() + ": point data \"" + name + "\" does not have one value per vertex");
    vtkNew<vtkDoubleArray> a;
    a->SetName(name.c_str());
    a->SetNumberOfValues(values.size());
    for (Eigen::Index i = 0; i < values.size(); ++i) a->SetValue(i, values[i]);
    pd->GetPointData()->AddArray(a);
    if (!pd->GetPointData()->GetScalars()) pd->GetPointData()->SetActiveScalars(name.c_str());
  }
  std::filesystem::path tmp = file;
  tmp += ".tmp" + std::to_string(::getpid());
  vtkNew<vtkXMLPolyDataWriter> w;
  w->SetFileName(tmp.string().c_str());
  w->SetInputData(pd);
  w->SetDataModeToBinary();
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
