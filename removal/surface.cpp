#include "removal/surface.hpp"

#include <cmath>
#include <vector>

namespace vmsim::removal {

core::TriangleMesh heightfield_mesh(const core::HeightGrid& g, double bottom, const core::HeightGrid* dev) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  const bool closed = g.z_mm.allFinite() && nx >= 2 && ny >= 2;
  core::TriangleMesh m;
  std::vector<Eigen::Vector3d> v;
  std::vector<double> d;
  std::vector<Eigen::Vector3i> t;
  std::vector<int> id(static_cast<std::size_t>(nx * ny), -1);
  for (Eigen::Index j = 0; j < ny; ++j)
    for (Eigen::Index i = 0; i < nx; ++i)
      if (std::isfinite(g.z_mm(j, i))) {
        id[static_cast<std::size_t>(j * nx + i)] = static_cast<int>(v.size());
        v.emplace_back(g.x(i), g.y(j), g.z_mm(j, i));
        d.push_back(dev && std::isfinite(dev->z_mm(j, i)) ? dev->z_mm(j, i) : 0.0);
      }
  auto at = [&](Eigen::Index j, Eigen::Index i) { return id[static_cast<std::size_t>(j * nx + i)]; };
  for (Eigen::Index j = 0; j + 1 < ny; ++j)
    for (Eigen::Index i = 0; i + 1 < nx; ++i) {
      const int a = at(j, i), b = at(j, i + 1), c = at(j + 1, i + 1), e = at(j + 1, i);
      // Counter-clockwise seen from above (+Z is outside).
      if (a >= 0 && b >= 0 && c >= 0) t.emplace_back(a, b, c);
      if (a >= 0 && c >= 0 && e >= 0) t.emplace_back(a, c, e);
    }
  if (closed) {
    // Bottom copies of the boundary nodes, walls between them, and a bottom fan of two triangles per cell along
    // the boundary would leave T-junctions: the bottom is a plain grid too (same nodes, z = bottom).
    const int base = static_cast<int>(v.size());
    for (Eigen::Index j = 0; j < ny; ++j)
      for (Eigen::Index i = 0; i < nx; ++i) {
        v.emplace_back(g.x(i), g.y(j), bottom);
        d.push_back(0.0);
      }
    auto bot = [&](Eigen::Index j, Eigen::Index i) { return base + static_cast<int>(j * nx + i); };
    for (Eigen::Index j = 0; j + 1 < ny; ++j)
      for (Eigen::Index i = 0; i + 1 < nx; ++i) {
        t.emplace_back(bot(j, i), bot(j + 1, i + 1), bot(j, i + 1));  // facing -Z
        t.emplace_back(bot(j, i), bot(j + 1, i), bot(j + 1, i + 1));
      }
    // Walls, outward normals.
    for (Eigen::Index i = 0; i + 1 < nx; ++i) {
      t.emplace_back(at(0, i), bot(0, i), bot(0, i + 1));  // y = y0 side, facing -Y
      t.emplace_back(at(0, i), bot(0, i + 1), at(0, i + 1));
      const Eigen::Index j = ny - 1;  // facing +Y
      t.emplace_back(at(j, i), at(j, i + 1), bot(j, i + 1));
      t.emplace_back(at(j, i), bot(j, i + 1), bot(j, i));
    }
    for (Eigen::Index j = 0; j + 1 < ny; ++j) {
      t.emplace_back(at(j, 0), at(j + 1, 0), bot(j + 1, 0));  // x = x0 side, facing -X
      t.emplace_back(at(j, 0), bot(j + 1, 0), bot(j, 0));
      const Eigen::Index i = nx - 1;  // facing +X
      t.emplace_back(at(j, i), bot(j, i), bot(j + 1, i));
      t.emplace_back(at(j, i), bot(j + 1, i), at(j + 1, i));
    }
  }
  m.vertices_mm.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t k = 0; k < v.size(); ++k) m.vertices_mm.row(static_cast<Eigen::Index>(k)) = v[k].transpose();
  m.triangles.resize(static_cast<Eigen::Index>(t.size()), 3);
  for (std::size_t k = 0; k < t.size(); ++k) m.triangles.row(static_cast<Eigen::Index>(k)) = t[k].transpose();
  if (dev) m.point_data.emplace_back("deviation_mm", Eigen::Map<Eigen::VectorXd>(d.data(), static_cast<Eigen::Index>(d.size())));
  return m;
}

}  // namespace vmsim::removal
