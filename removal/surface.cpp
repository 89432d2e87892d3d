#include "removal/surface.hpp"

#include <cmath>
#include <utility>
#include <vector>

namespace vmsim::removal {

core::TriangleMesh heightfield_mesh(const core::HeightGrid& g, double bottom, const core::HeightGrid* dev) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  const bool closed = g.z_mm.allFinite() && nx >= 2 && ny >= 2;
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
  return close_heightfield_top(g, bottom, id, std::move(v), std::move(d), std::move(t), closed, dev != nullptr);
}

core::TriangleMesh close_heightfield_top(const core::HeightGrid& g, double bottom, const std::vector<int>& id,
                                         std::vector<Eigen::Vector3d> v, std::vector<double> d,
                                         std::vector<Eigen::Vector3i> t, bool closed, bool dev) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  auto at = [&](Eigen::Index j, Eigen::Index i) { return id[static_cast<std::size_t>(j * nx + i)]; };
  core::TriangleMesh m;
  if (closed) {
    // The bottom: only the boundary nodes (no T-junctions with the walls), in a fan about the bottom's centre,
    // which keeps every triangle proper and the mesh small (the top carries the detail).
    std::vector<std::pair<Eigen::Index, Eigen::Index>> ring;  // boundary nodes, counter-clockwise from above
    for (Eigen::Index i = 0; i < nx; ++i) ring.emplace_back(0, i);
    for (Eigen::Index j = 1; j < ny; ++j) ring.emplace_back(j, nx - 1);
    for (Eigen::Index i = nx - 2; i >= 0; --i) ring.emplace_back(ny - 1, i);
    for (Eigen::Index j = ny - 2; j >= 1; --j) ring.emplace_back(j, 0);
    const int base = static_cast<int>(v.size());
    for (const auto& [j, i] : ring) {
      v.emplace_back(g.x(i), g.y(j), bottom);
      d.push_back(0.0);
    }
    const int centre = static_cast<int>(v.size());
    // The fan's centre sits inside a grid cell at an irrational fraction of it, so that rays on this grid or on
    // finer regular grids (reading the part back) do not pass through the vertex all the fan's triangles share.
    v.emplace_back(g.x((nx - 1) / 2) + 0.3183098861837907 * g.dx_mm, g.y((ny - 1) / 2) + 0.2718281828459045 * g.dy_mm,
                   bottom);
    d.push_back(0.0);
    const int nr = static_cast<int>(ring.size());
    for (int k = 0; k < nr; ++k) {
      const int a = base + k, b = base + (k + 1) % nr;
      t.emplace_back(centre, b, a);  // facing -Z
      // Wall between top ring node k, k+1 and their bottom copies, facing outwards.
      const int ta = at(ring[static_cast<std::size_t>(k)].first, ring[static_cast<std::size_t>(k)].second);
      const int tb =
          at(ring[static_cast<std::size_t>((k + 1) % nr)].first, ring[static_cast<std::size_t>((k + 1) % nr)].second);
      t.emplace_back(ta, a, b);
      t.emplace_back(ta, b, tb);
    }
  }
  m.vertices_mm.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t k = 0; k < v.size(); ++k) m.vertices_mm.row(static_cast<Eigen::Index>(k)) = v[k].transpose();
  m.triangles.resize(static_cast<Eigen::Index>(t.size()), 3);
  for (std::size_t k = 0; k < t.size(); ++k) m.triangles.row(static_cast<Eigen::Index>(k)) = t[k].transpose();
  if (dev)
    m.point_data.emplace_back("deviation_mm",
                              Eigen::Map<Eigen::VectorXd>(d.data(), static_cast<Eigen::Index>(d.size())));
  return m;
}

}  // namespace vmsim::removal
