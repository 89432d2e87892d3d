#include "sim/part_mesh.hpp"

#include "core/error.hpp"
#include "removal/surface.hpp"

#include <fmt/format.h>

#include <cmath>
#include <utility>
#include <vector>

namespace vmsim::sim {

Eigen::Index heightfield_mesh_triangles(const core::HeightGrid& top) {
  const Eigen::Index nx = top.nx(), ny = top.ny();
  const auto valid = [&](Eigen::Index j, Eigen::Index i) { return std::isfinite(top.z_mm(j, i)); };
  Eigen::Index n = 0;
  for (Eigen::Index j = 0; j + 1 < ny; ++j)
    for (Eigen::Index i = 0; i + 1 < nx; ++i) {
      const bool a = valid(j, i), b = valid(j, i + 1), c = valid(j + 1, i + 1), e = valid(j + 1, i);
      n += (a && b && c) + (a && c && e);
    }
  if (top.z_mm.allFinite() && nx >= 2 && ny >= 2) n += 3 * (2 * nx + 2 * ny - 4);
  return n;
}

namespace {

// Whether the (B+1)^2 values of a block starting at (j0, i0) lie within tol of their least-squares plane. On a
// regular grid centred at the block's centre the fit is closed-form: mean, and slopes sum(z u) / sum(u^2).
bool flat(const core::HeightArray& z, Eigen::Index j0, Eigen::Index i0, int B, double tol) {
  const auto blk = z.block(j0, i0, B + 1, B + 1);
  if (!blk.allFinite()) return false;
  const double h = B / 2.0, mean = blk.mean();
  double su = 0, sv = 0, uu = 0;
  for (int j = 0; j <= B; ++j)
    for (int i = 0; i <= B; ++i) {
      su += blk(j, i) * (i - h), sv += blk(j, i) * (j - h);
      uu += (i - h) * (i - h);
    }
  const double a = su / uu, b = sv / uu;  // sum(v^2) = sum(u^2) on a square block
  for (int j = 0; j <= B; ++j)
    for (int i = 0; i <= B; ++i)
      if (std::abs(blk(j, i) - (mean + a * (i - h) + b * (j - h))) > tol) return false;
  return true;
}

}  // namespace

SimplifiedMesh simplified_heightfield_mesh(const core::HeightGrid& g, double bottom, const core::HeightGrid* dev,
                                           double tol, int B) {
  if (!(tol > 0) || !std::isfinite(tol))
    throw core::Error(fmt::format("simplified part mesh: tolerance {} mm is not positive", tol));
  if (B < 2 || B % 2 != 0) throw core::Error(fmt::format("simplified part mesh: block of {} cells is not even", B));
  const Eigen::Index nx = g.nx(), ny = g.ny();
  if (dev && (dev->nx() != nx || dev->ny() != ny))
    throw core::Error("simplified part mesh: the deviation grid is not the surface's grid");
  const bool closed = g.z_mm.allFinite() && nx >= 2 && ny >= 2;
  const Eigen::Index bx = (nx - 1) / B, by = (ny - 1) / B;  // whole blocks
  SimplifiedMesh out;
  out.blocks = bx * by;
  out.error_bound_mm = 2 * tol;
  std::vector<char> is_flat(static_cast<std::size_t>(bx * by), 0);
  // Nodes drawn: all but the interior nodes of flat blocks (their centre node stays, the fan's apex).
  std::vector<char> used(static_cast<std::size_t>(nx * ny), 1);
  for (Eigen::Index J = 0; J < by; ++J)
    for (Eigen::Index I = 0; I < bx; ++I) {
      const Eigen::Index j0 = J * B, i0 = I * B;
      if (!flat(g.z_mm, j0, i0, B, tol) || (dev && !flat(dev->z_mm, j0, i0, B, tol))) continue;
      is_flat[static_cast<std::size_t>(J * bx + I)] = 1;
      ++out.flat_blocks;
      for (Eigen::Index j = j0 + 1; j < j0 + B; ++j)
        for (Eigen::Index i = i0 + 1; i < i0 + B; ++i)
          used[static_cast<std::size_t>(j * nx + i)] = j == j0 + B / 2 && i == i0 + B / 2;
    }
  std::vector<Eigen::Vector3d> v;
  std::vector<double> d;
  std::vector<Eigen::Vector3i> t;
  std::vector<int> id(static_cast<std::size_t>(nx * ny), -1);
  for (Eigen::Index j = 0; j < ny; ++j)
    for (Eigen::Index i = 0; i < nx; ++i)
      if (used[static_cast<std::size_t>(j * nx + i)] && std::isfinite(g.z_mm(j, i))) {
        id[static_cast<std::size_t>(j * nx + i)] = static_cast<int>(v.size());
        v.emplace_back(g.x(i), g.y(j), g.z_mm(j, i));
        d.push_back(dev && std::isfinite(dev->z_mm(j, i)) ? dev->z_mm(j, i) : 0.0);
      }
  auto at = [&](Eigen::Index j, Eigen::Index i) { return id[static_cast<std::size_t>(j * nx + i)]; };
  auto in_flat = [&](Eigen::Index j, Eigen::Index i) {  // the cell (j, i)..(j+1, i+1)
    const Eigen::Index J = j / B, I = i / B;
    return J < by && I < bx && is_flat[static_cast<std::size_t>(J * bx + I)];
  };
  for (Eigen::Index j = 0; j + 1 < ny; ++j)
    for (Eigen::Index i = 0; i + 1 < nx; ++i) {
      if (in_flat(j, i)) continue;
      const int a = at(j, i), b = at(j, i + 1), c = at(j + 1, i + 1), e = at(j + 1, i);
      // As removal::heightfield_mesh: counter-clockwise seen from above (+Z is outside).
      if (a >= 0 && b >= 0 && c >= 0) t.emplace_back(a, b, c);
      if (a >= 0 && c >= 0 && e >= 0) t.emplace_back(a, c, e);
    }
  for (Eigen::Index J = 0; J < by; ++J)
    for (Eigen::Index I = 0; I < bx; ++I) {
      if (!is_flat[static_cast<std::size_t>(J * bx + I)]) continue;
      const Eigen::Index j0 = J * B, i0 = I * B;
      std::vector<int> ring;  // the block's boundary nodes, counter-clockwise from above
      for (Eigen::Index i = i0; i < i0 + B; ++i) ring.push_back(at(j0, i));
      for (Eigen::Index j = j0; j < j0 + B; ++j) ring.push_back(at(j, i0 + B));
      for (Eigen::Index i = i0 + B; i > i0; --i) ring.push_back(at(j0 + B, i));
      for (Eigen::Index j = j0 + B; j > j0; --j) ring.push_back(at(j, i0));
      const int centre = at(j0 + B / 2, i0 + B / 2);
      for (std::size_t k = 0; k < ring.size(); ++k) t.emplace_back(centre, ring[k], ring[(k + 1) % ring.size()]);
    }
  // Walls and bottom as removal::heightfield_mesh makes them.
  out.mesh = removal::close_heightfield_top(g, bottom, id, std::move(v), std::move(d), std::move(t), closed, dev != nullptr);
  return out;
}

}  // namespace vmsim::sim
