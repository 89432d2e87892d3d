#include "metrology/mesh_distance.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

namespace vmsim::metrology {

namespace {

using V3 = Eigen::Vector3d;

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, section 5.1.5: Voronoi regions of
// the vertices, edges and face, in that order).
V3 closest_on_triangle(const V3& p, const V3& a, const V3& b, const V3& c) {
  const V3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const V3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const V3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace

// Box and Node are Impl's own (not in the anonymous namespace: a member of a class with linkage cannot have such a
// type, and GCC warns in unity builds).
struct MeshDistance::Impl {
  struct Box {
    V3 lo = V3::Constant(HUGE_VAL), hi = V3::Constant(-HUGE_VAL);
    void grow(const V3& p) { lo = lo.cwiseMin(p), hi = hi.cwiseMax(p); }
    void grow(const Box& b) { lo = lo.cwiseMin(b.lo), hi = hi.cwiseMax(b.hi); }
    double dist2(const V3& p) const { return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm(); }
  };

  struct Node {
    Box box;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int first = 0, count = 0;   // leaf: triangles order[first, first + count)
  };

  std::vector<V3> a, b, c, n;  // per triangle: corners and unit normal
  std::vector<int> order;
  std::vector<Node> nodes;

  int build(int first, int count, std::vector<V3>& centroid) {
    Node nd;
    for (int k = first; k < first + count; ++k) {
      const int t = order[static_cast<std::size_t>(k)];
      nd.box.grow(a[static_cast<std::size_t>(t)]), nd.box.grow(b[static_cast<std::size_t>(t)]),
          nd.box.grow(c[static_cast<std::size_t>(t)]);
    }
    const int id = static_cast<int>(nodes.size());
    nodes.push_back(nd);
    if (count <= 4) {
      nodes[static_cast<std::size_t>(id)].first = first, nodes[static_cast<std::size_t>(id)].count = count;
      return id;
    }
    Box cb;
    for (int k = first; k < first + count; ++k)
      cb.grow(centroid[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])]);
    int axis = 0;
    (cb.hi - cb.lo).maxCoeff(&axis);
    const int mid = first + count / 2;
    std::nth_element(order.begin() + first, order.begin() + mid, order.begin() + first + count, [&](int u, int v) {
      const double cu = centroid[static_cast<std::size_t>(u)][axis], cv = centroid[static_cast<std::size_t>(v)][axis];
      return cu < cv || (cu == cv && u < v);  // ties by index: the same tree every time
    });
    const int l = build(first, mid - first, centroid);
    const int r = build(mid, first + count - mid, centroid);
    nodes[static_cast<std::size_t>(id)].left = l, nodes[static_cast<std::size_t>(id)].right = r;
    return id;
  }
};

MeshDistance::MeshDistance(const core::TriangleMesh& m) : impl_(std::make_unique<Impl>()) {
  const Eigen::Index nt = m.triangles.rows(), nv = m.vertices_mm.rows();
  if (nt == 0) throw core::Error("mesh distance: the mesh has no triangles");
  Impl& I = *impl_;
  std::vector<V3> centroid;
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k)
      if (m.triangles(t, k) < 0 || m.triangles(t, k) >= nv)
        throw core::Error(fmt::format("mesh distance: triangle {} names vertex {} of {}", t, m.triangles(t, k), nv));
    const V3 A = m.vertices_mm.row(m.triangles(t, 0)).transpose(), B = m.vertices_mm.row(m.triangles(t, 1)).transpose(),
             C = m.vertices_mm.row(m.triangles(t, 2)).transpose();
    const V3 nn = (B - A).cross(C - A);
    if (!(nn.norm() > 0)) continue;  // degenerate: no area, no normal, nothing to be closest to that its edges lack
    I.a.push_back(A), I.b.push_back(B), I.c.push_back(C), I.n.push_back(nn.normalized());
    centroid.push_back((A + B + C) / 3);
  }
  if (I.a.empty()) throw core::Error("mesh distance: every triangle of the mesh is degenerate");
  I.order.resize(I.a.size());
  std::iota(I.order.begin(), I.order.end(), 0);
  I.nodes.reserve(2 * I.a.size() / 4 + 8);
  I.build(0, static_cast<int>(I.a.size()), centroid);
}

MeshDistance::~MeshDistance() = default;

MeshDistance::Hit MeshDistance::closest(const V3& p) const {
  const Impl& I = *impl_;
  double best = HUGE_VAL;
  int best_t = -1;
  V3 best_c = V3::Zero();
  std::array<int, 128> stack;
  int sp = 0;
  stack[static_cast<std::size_t>(sp++)] = 0;
  while (sp > 0) {
    const Impl::Node& nd = I.nodes[static_cast<std::size_t>(stack[static_cast<std::size_t>(--sp)])];
    if (nd.box.dist2(p) > best) continue;
    if (nd.left < 0) {
      for (int k = nd.first; k < nd.first + nd.count; ++k) {
        const int t = I.order[static_cast<std::size_t>(k)];
        const V3 q = closest_on_triangle(p, I.a[static_cast<std::size_t>(t)], I.b[static_cast<std::size_t>(t)],
                                         I.c[static_cast<std::size_t>(t)]);
        const double d2 = (p - q).squaredNorm();
        // Equal distances (a point closest to an edge or a vertex): the lower triangle index, for repeatability.
        if (d2 < best || (d2 == best && t < best_t)) best = d2, best_t = t, best_c = q;
      }
      continue;
    }
    // Nearer child last, so it is visited first.
    const double dl = I.nodes[static_cast<std::size_t>(nd.left)].box.dist2(p),
                 dr = I.nodes[static_cast<std::size_t>(nd.right)].box.dist2(p);
    if (sp + 2 > static_cast<int>(stack.size())) throw core::Error("mesh distance: hierarchy deeper than 128 levels");
    if (dl < dr)
      stack[static_cast<std::size_t>(sp++)] = nd.right, stack[static_cast<std::size_t>(sp++)] = nd.left;
    else
      stack[static_cast<std::size_t>(sp++)] = nd.left, stack[static_cast<std::size_t>(sp++)] = nd.right;
  }
  Hit h;
  h.triangle = best_t;
  h.closest = best_c;
  const double d = std::sqrt(best);
  h.distance = (p - best_c).dot(I.n[static_cast<std::size_t>(best_t)]) < 0 ? -d : d;
  return h;
}

Eigen::VectorXd signed_distances(const Eigen::Matrix<double, Eigen::Dynamic, 3>& pts, const core::TriangleMesh& mesh) {
  const MeshDistance md(mesh);
  Eigen::VectorXd d(pts.rows());
#pragma omp parallel for schedule(dynamic, 256)
  for (Eigen::Index k = 0; k < pts.rows(); ++k) d[k] = md.closest(pts.row(k).transpose()).distance;
  return d;
}

core::HeightGrid mesh_deviation(const core::HeightGrid& scan, const RigidTransform& T, const core::TriangleMesh& mesh) {
  const MeshDistance md(mesh);
  core::HeightGrid out = scan;
#pragma omp parallel for schedule(dynamic, 4)
  for (Eigen::Index j = 0; j < scan.ny(); ++j)
    for (Eigen::Index i = 0; i < scan.nx(); ++i)
      if (scan.valid(j, i)) out.z_mm(j, i) = md.closest(T.apply(V3(scan.x(i), scan.y(j), scan.z_mm(j, i)))).distance;
  return out;
}

core::TriangleMesh grid_surface_mesh(const core::HeightGrid& g) {
  core::TriangleMesh m;
  const Eigen::Index nx = g.nx(), ny = g.ny();
  std::vector<int> id(static_cast<std::size_t>(nx * ny), -1);
  std::vector<V3> v;
  for (Eigen::Index j = 0; j < ny; ++j)
    for (Eigen::Index i = 0; i < nx; ++i)
      if (g.valid(j, i)) {
        id[static_cast<std::size_t>(j * nx + i)] = static_cast<int>(v.size());
        v.emplace_back(g.x(i), g.y(j), g.z_mm(j, i));
      }
  std::vector<std::array<int, 3>> t;
  for (Eigen::Index j = 0; j + 1 < ny; ++j)
    for (Eigen::Index i = 0; i + 1 < nx; ++i) {
      const int a = id[static_cast<std::size_t>(j * nx + i)], b = id[static_cast<std::size_t>(j * nx + i + 1)];
      const int c = id[static_cast<std::size_t>((j + 1) * nx + i)],
                d = id[static_cast<std::size_t>((j + 1) * nx + i + 1)];
      if (a < 0 || b < 0 || c < 0 || d < 0) continue;
      t.push_back({a, b, d});  // counter-clockwise seen from above: normal +z
      t.push_back({a, d, c});
    }
  m.vertices_mm.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t k = 0; k < v.size(); ++k) m.vertices_mm.row(static_cast<Eigen::Index>(k)) = v[k].transpose();
  m.triangles.resize(static_cast<Eigen::Index>(t.size()), 3);
  for (std::size_t k = 0; k < t.size(); ++k)
    for (int c = 0; c < 3; ++c) m.triangles(static_cast<Eigen::Index>(k), c) = t[k][static_cast<std::size_t>(c)];
  return m;
}

core::HeightGrid rasterize_top(const core::TriangleMesh& m, double h) {
  if (m.vertices_mm.rows() == 0 || m.triangles.rows() == 0) throw core::Error("rasterize: the mesh is empty");
  if (!(h > 0)) throw core::Error("rasterize: the spacing must be positive");
  const Eigen::Vector3d lo = m.vertices_mm.colwise().minCoeff().transpose(),
                        hi = m.vertices_mm.colwise().maxCoeff().transpose();
  const double nxd = std::floor((hi.x() - lo.x()) / h + 1e-9) + 1, nyd = std::floor((hi.y() - lo.y()) / h + 1e-9) + 1;
  if (!(nxd * nyd <= static_cast<double>(1LL << 28)))
    throw core::Error(
        fmt::format("rasterize: a {:.0f} x {:.0f} grid at {} mm is too large; choose a larger spacing", nxd, nyd, h));
  core::HeightGrid g;
  g.x0_mm = lo.x(), g.y0_mm = lo.y(), g.dx_mm = g.dy_mm = h;
  g.z_mm = core::HeightArray::Constant(static_cast<Eigen::Index>(nyd), static_cast<Eigen::Index>(nxd), -HUGE_VAL);
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t) {
    const int ia = m.triangles(t, 0), ib = m.triangles(t, 1), ic = m.triangles(t, 2);
    if (ia < 0 || ib < 0 || ic < 0 || ia >= m.vertices_mm.rows() || ib >= m.vertices_mm.rows() ||
        ic >= m.vertices_mm.rows())
      throw core::Error(fmt::format("rasterize: triangle {} names a vertex out of range", t));
    const V3 A = m.vertices_mm.row(ia).transpose(), B = m.vertices_mm.row(ib).transpose(),
             C = m.vertices_mm.row(ic).transpose();
    const double area2 = (B.x() - A.x()) * (C.y() - A.y()) - (C.x() - A.x()) * (B.y() - A.y());  // 2 x signed xy area
    if (!(area2 > 0)) continue;  // facing down, vertical or degenerate
    const auto i0 = static_cast<Eigen::Index>(std::ceil((std::min({A.x(), B.x(), C.x()}) - g.x0_mm) / h - 1e-9));
    const auto i1 = static_cast<Eigen::Index>(std::floor((std::max({A.x(), B.x(), C.x()}) - g.x0_mm) / h + 1e-9));
    const auto j0 = static_cast<Eigen::Index>(std::ceil((std::min({A.y(), B.y(), C.y()}) - g.y0_mm) / h - 1e-9));
    const auto j1 = static_cast<Eigen::Index>(std::floor((std::max({A.y(), B.y(), C.y()}) - g.y0_mm) / h + 1e-9));
    for (Eigen::Index j = std::max<Eigen::Index>(j0, 0); j <= std::min<Eigen::Index>(j1, g.ny() - 1); ++j)
      for (Eigen::Index i = std::max<Eigen::Index>(i0, 0); i <= std::min<Eigen::Index>(i1, g.nx() - 1); ++i) {
        const double x = g.x(i), y = g.y(j);
        // Barycentric weights; a small tolerance so nodes on shared edges are covered by one of the triangles.
        const double wa = ((B.x() - x) * (C.y() - y) - (C.x() - x) * (B.y() - y)) / area2;
        const double wb = ((C.x() - x) * (A.y() - y) - (A.x() - x) * (C.y() - y)) / area2;
        const double wc = 1 - wa - wb;
        if (wa < -1e-9 || wb < -1e-9 || wc < -1e-9) continue;
        g.z_mm(j, i) = std::max(g.z_mm(j, i), wa * A.z() + wb * B.z() + wc * C.z());
      }
  }
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k)
    if (g.z_mm.data()[k] == -HUGE_VAL) g.z_mm.data()[k] = std::numeric_limits<double>::quiet_NaN();
  return g;
}

}  // namespace vmsim::metrology
