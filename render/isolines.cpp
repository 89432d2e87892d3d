// Iso-lines by VTK's flying edges (marching squares) on the grid in index space, then mapped to the nodes'
// coordinates: each point lies on one grid edge, so one interpolation parameter places it in x, y and z.
#include "render/isolines.hpp"

#include "core/error.hpp"
#include "render/detail.hpp"

#include <vtkCellArray.h>
#include <vtkFlyingEdges2D.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace vmsim::render {

IsoLines grid_isolines(std::span<const double> x_mm, std::span<const double> y_mm, std::span<const float> values,
                       std::span<const float> z_mm, std::span<const double> levels) {
  const auto nx = static_cast<vtkIdType>(x_mm.size()), ny = static_cast<vtkIdType>(y_mm.size());
  if (nx < 2 || ny < 2) throw core::Error(fmt::format("grid_isolines: {} x {} nodes, at least 2 x 2 needed", nx, ny));
  if (values.size() != static_cast<std::size_t>(nx * ny) || z_mm.size() != values.size())
    throw core::Error(
        fmt::format("grid_isolines: {} values and {} heights for {} x {} nodes", values.size(), z_mm.size(), nx, ny));
  for (std::span<const double> c : {x_mm, y_mm})
    for (std::size_t k = 1; k < c.size(); ++k)
      if (!(c[k] > c[k - 1])) throw core::Error("grid_isolines: node coordinates are not ascending");
  IsoLines out;
  if (levels.empty()) return out;

  vtkNew<vtkImageData> image;
  image->SetDimensions(static_cast<int>(nx), static_cast<int>(ny), 1);
  image->SetOrigin(0, 0, 0);
  image->SetSpacing(1, 1, 1);
  vtkNew<vtkFloatArray> scalars;
  scalars->SetName("values");
  // Borrowed, not copied (save = 1: VTK never frees it); the filter only reads its input.
  scalars->SetArray(const_cast<float*>(values.data()), nx * ny, 1);
  image->GetPointData()->SetScalars(scalars);

  detail::VtkMessages messages;
  vtkNew<vtkFlyingEdges2D> fe;
  fe->SetInputData(image);
  fe->SetNumberOfContours(static_cast<int>(levels.size()));
  for (std::size_t k = 0; k < levels.size(); ++k) fe->SetValue(static_cast<int>(k), levels[k]);
  fe->ComputeScalarsOff();
  fe->Update();
  messages.check("iso-lines");
  vtkPolyData* pd = fe->GetOutput();
  const vtkIdType np = pd->GetNumberOfPoints();

  // Each point: the grid edge it lies on (the coordinate nearest a whole index is the edge's fixed one) and its
  // parameter along it. A point interpolated towards a NaN node is NaN itself: dropped with its segments.
  std::vector<std::int32_t> row(static_cast<std::size_t>(np), -1);
  out.points_mm.resize(np, 3);
  std::int32_t n = 0;
  for (vtkIdType p = 0; p < np; ++p) {
    double u[3];
    pd->GetPoint(p, u);
    if (!std::isfinite(u[0]) || !std::isfinite(u[1])) continue;
    const double ru = std::round(u[0]), rv = std::round(u[1]);
    double x, y, z;
    if (std::abs(u[0] - ru) <= std::abs(u[1] - rv)) {  // on the edge from node (i, j) to (i, j + 1)
      const auto i = std::clamp<vtkIdType>(static_cast<vtkIdType>(ru), 0, nx - 1);
      const auto j = std::clamp<vtkIdType>(static_cast<vtkIdType>(std::floor(u[1])), 0, ny - 2);
      const double t = std::clamp(u[1] - static_cast<double>(j), 0.0, 1.0);
      x = x_mm[static_cast<std::size_t>(i)];
      y = y_mm[static_cast<std::size_t>(j)] +
          t * (y_mm[static_cast<std::size_t>(j + 1)] - y_mm[static_cast<std::size_t>(j)]);
      const double z0 = z_mm[static_cast<std::size_t>(j * nx + i)],
                   z1 = z_mm[static_cast<std::size_t>((j + 1) * nx + i)];
      z = z0 + t * (z1 - z0);
    } else {  // on the edge from node (i, j) to (i + 1, j)
      const auto j = std::clamp<vtkIdType>(static_cast<vtkIdType>(rv), 0, ny - 1);
      const auto i = std::clamp<vtkIdType>(static_cast<vtkIdType>(std::floor(u[0])), 0, nx - 2);
      const double t = std::clamp(u[0] - static_cast<double>(i), 0.0, 1.0);
      x = x_mm[static_cast<std::size_t>(i)] +
          t * (x_mm[static_cast<std::size_t>(i + 1)] - x_mm[static_cast<std::size_t>(i)]);
      y = y_mm[static_cast<std::size_t>(j)];
      const double z0 = z_mm[static_cast<std::size_t>(j * nx + i)], z1 = z_mm[static_cast<std::size_t>(j * nx + i + 1)];
      z = z0 + t * (z1 - z0);
    }
    if (!std::isfinite(z)) continue;
    out.points_mm.row(n) << x, y, z;
    row[static_cast<std::size_t>(p)] = n++;
  }
  out.points_mm.conservativeResize(n, 3);

  vtkCellArray* lines = pd->GetLines();
  out.segments.reserve(static_cast<std::size_t>(lines->GetNumberOfCells()));
  vtkIdType npts = 0;
  const vtkIdType* ids = nullptr;
  for (lines->InitTraversal(); lines->GetNextCell(npts, ids);)
    for (vtkIdType k = 0; k + 1 < npts; ++k) {
      const std::int32_t a = row[static_cast<std::size_t>(ids[k])], b = row[static_cast<std::size_t>(ids[k + 1])];
      if (a >= 0 && b >= 0) out.segments.push_back({a, b});
    }
  return out;
}

}  // namespace vmsim::render
