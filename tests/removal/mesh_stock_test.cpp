// Mesh stocks through Embree against independent references:
//   - a 12-triangle box read back from an STL file fills z-maps, tri-dexel grids and needles exactly as fill_box
//     does with the same box (the stored floats compared bit for bit), also far from the origin, and stays equal
//     after the same sweeps are cut from both;
//   - concave solids (a C-shaped prism, a frame with a through-hole) give the intervals worked out by hand;
//   - rays through shared edges and vertices, along faces and touching silhouettes get the right parity;
//   - rays through (and within rounding or tau of) vertices shared by hundreds of long thin triangles: the centre
//     of a fan-capped prism, heightfield_mesh's bottom fan, the apices of a double pyramid (regressions: these
//     came back empty or unresolved while degenerate rays were re-cast shifted by a finite distance);
//   - open, flipped and non-manifold meshes are refused with the file's name;
//   - results do not depend on the thread count.
#include "core/error.hpp"
#include "core/stl.hpp"
#include "removal/cut.hpp"
#include "removal/fields.hpp"
#include "removal/mesh_stock.hpp"
#include "removal/surface.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numbers>
#include <random>

namespace fs = std::filesystem;
using namespace vmsim::removal;
using vmsim::core::TriangleMesh;

namespace {

fs::path work() {
  const fs::path d = fs::path(VMSIM_BINARY_DIR) / "tests" / "removal" / "work" / "mesh_stock";
  fs::create_directories(d);
  return d;
}

TriangleMesh box_mesh(const Box& b) {
  TriangleMesh m;
  m.vertices_mm.resize(8, 3);
  for (int k = 0; k < 8; ++k)
    m.vertices_mm.row(k) << ((k & 1) ? b.hi.x() : b.lo.x()), ((k & 2) ? b.hi.y() : b.lo.y()),
        ((k & 4) ? b.hi.z() : b.lo.z());
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3,
      7, 5;
  return m;
}

// A prism: closed profile loops in the (u, v) plane (outer counter-clockwise, holes clockwise) with a
// triangulation of the region they bound (counter-clockwise triangles), extruded along w = u x v over [w0, w1].
TriangleMesh prism(const std::vector<Eigen::Vector2d>& pts, const std::vector<std::vector<int>>& loops,
                   const std::vector<std::array<int, 3>>& cap, const Eigen::Vector3d& U, const Eigen::Vector3d& V,
                   double w0, double w1) {
  const Eigen::Vector3d W = U.cross(V);
  const int n = static_cast<int>(pts.size());
  TriangleMesh m;
  m.vertices_mm.resize(2 * n, 3);
  for (int k = 0; k < n; ++k) {
    m.vertices_mm.row(k) = (pts[k].x() * U + pts[k].y() * V + w0 * W).transpose();
    m.vertices_mm.row(n + k) = (pts[k].x() * U + pts[k].y() * V + w1 * W).transpose();
  }
  std::vector<std::array<int, 3>> t;
  for (const auto& c : cap) {
    t.push_back({c[0], c[2], c[1]});              // bottom, facing -w
    t.push_back({n + c[0], n + c[1], n + c[2]});  // top, facing +w
  }
  for (const auto& loop : loops)
    for (std::size_t k = 0; k < loop.size(); ++k) {
      const int p = loop[k], q = loop[(k + 1) % loop.size()];
      t.push_back({p, q, n + q});
      t.push_back({p, n + q, n + p});
    }
  m.triangles.resize(static_cast<Eigen::Index>(t.size()), 3);
  for (std::size_t k = 0; k < t.size(); ++k) m.triangles.row(static_cast<Eigen::Index>(k)) << t[k][0], t[k][1], t[k][2];
  return m;
}

double signed_volume(const TriangleMesh& m) {
  double v = 0;
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t) {
    const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(t, 0)), b = m.vertices_mm.row(m.triangles(t, 1)),
                          c = m.vertices_mm.row(m.triangles(t, 2));
    v += a.dot(b.cross(c)) / 6;
  }
  return v;
}

// The mesh through a binary STL file and back, as a job would load it.
TriangleMesh via_stl(const TriangleMesh& m, const std::string& name) {
  const fs::path p = work() / name;
  vmsim::core::write_stl_binary(p, m);
  TriangleMesh r = vmsim::core::read_stl(p);
  vmsim::core::check_closed(r, p.string());
  return r;
}

using vmsim::removal::test::same_bits;

std::string show(const std::vector<Interval>& iv) {
  std::string s = "{";
  for (const auto& x : iv) s += " [" + std::to_string(x.lo) + ", " + std::to_string(x.hi) + "]";
  return s + " }";
}

// Every ray of two grids holds the same floats; returns the number of rays compared.
std::size_t expect_identical(const DexelGrid& a, const DexelGrid& b, const std::string& what) {
  EXPECT_EQ(a.nu(), b.nu());
  EXPECT_EQ(a.nv(), b.nv());
  std::vector<Interval> ia, ib;
  int reported = 0;
  std::size_t n = 0;
  for (int j = 0; j < a.nv(); ++j)
    for (int i = 0; i < a.nu(); ++i, ++n) {
      a.intervals(i, j, ia);
      b.intervals(i, j, ib);
      if (!same_bits(ia, ib) && reported++ < 8)
        ADD_FAILURE() << what << " ray (" << i << ", " << j << ") at " << a.ray_origin(i, j).transpose() << ": "
                      << show(ia) << " vs " << show(ib);
    }
  return n;
}

void expect_identical(const NeedleSet& a, const NeedleSet& b, const std::string& what) {
  std::vector<Interval> ia, ib;
  int reported = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    a.store().get(k, ia);
    b.store().get(k, ib);
    if (!same_bits(ia, ib) && reported++ < 8)
      ADD_FAILURE() << what << " needle " << k << " from " << a.origin(k).transpose() << " along "
                    << a.direction(k).transpose() << ": " << show(ia) << " vs " << show(ib);
  }
}

std::vector<SweptTool> some_sweeps(const Box& b) {
  // A ball end and a flat end crossing the top, a ball plunging through a side wall, a slanted pass.
  std::vector<SweptTool> s;
  const Eigen::Vector3d c = 0.5 * (b.lo + b.hi), e = b.hi - b.lo;
  SweptTool ball;
  ball.tool = Tool{5.0, 5.0, 50.0};
  ball.tip0 = Eigen::Vector3d(b.lo.x() - 6, c.y(), b.hi.z() - 1.3);
  ball.d = Eigen::Vector3d(e.x() + 12, 0.1 * e.y(), -0.7);
  s.push_back(ball);
  SweptTool flat;
  flat.tool = Tool{3.0, 0.0, 40.0};
  flat.tip0 = Eigen::Vector3d(c.x(), b.lo.y() - 4, b.hi.z() - 2.05);
  flat.d = Eigen::Vector3d(0.3 * e.x(), e.y() + 8, 0);
  s.push_back(flat);
  SweptTool side = ball;
  side.tip0 = Eigen::Vector3d(b.hi.x() + 1, c.y() + 0.37, c.z());
  side.axis = Eigen::Vector3d(1, 0, 0);
  side.d = Eigen::Vector3d(-4.1, 0, 0);
  s.push_back(side);
  SweptTool slant = flat;
  slant.tool = Tool{4.0, 1.0, 40.0};
  slant.tip0 = Eigen::Vector3d(b.lo.x() + 0.21 * e.x(), b.lo.y() + 0.1, b.hi.z() + 0.5);
  slant.d = Eigen::Vector3d(0.5 * e.x(), 0.6 * e.y(), -3.3);
  s.push_back(slant);
  return s;
}

// Needles: random ones through and around the box, and deliberately degenerate ones (through corners, along
// edges and faces, through the diagonals of the faces' triangle pairs).
NeedleSet needles_for(const Box& b, std::size_t random_count) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(0, 1);
  const Eigen::Vector3d e = b.hi - b.lo, c = 0.5 * (b.lo + b.hi);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  for (std::size_t k = 0; k < random_count; ++k) {
    const Eigen::Vector3d p = b.lo - 0.3 * e + Eigen::Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(1.6 * e);
    Eigen::Vector3d dir(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    if (dir.norm() < 1e-3) dir = Eigen::Vector3d::UnitZ();
    dir.normalize();
    o.push_back(p - 0.8 * e.norm() * dir);
    d.push_back(dir);
    len.push_back(e.norm() * (0.3 + 1.5 * u(rng)));
  }
  // Along the 12 edges and through the face planes (axis-aligned, starting outside).
  const double m = 3;
  for (int a = 0; a < 3; ++a) {
    const int b1 = (a + 1) % 3, b2 = (a + 2) % 3;
    for (double s1 : {b.lo[b1], b.hi[b1], c[b1]})
      for (double s2 : {b.lo[b2], b.hi[b2], c[b2]}) {
        Eigen::Vector3d p;
        p[a] = b.lo[a] - m;
        p[b1] = s1;
        p[b2] = s2;
        o.push_back(p);
        d.push_back(Eigen::Vector3d::Unit(a));
        len.push_back(e[a] + 2 * m);
      }
  }
  return NeedleSet(o, d, len);
}

// [t0, t1]: the line o + t d inside a convex closed mesh, as the largest entering and smallest leaving plane
// parameter over its faces; false when the line misses it (or runs parallel to a face outside its plane).
bool convex_clip(const TriangleMesh& m, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t0, double& t1) {
  t0 = -1e300, t1 = 1e300;
  for (Eigen::Index k = 0; k < m.triangles.rows(); ++k) {
    const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(k, 0)), b = m.vertices_mm.row(m.triangles(k, 1)),
                          c = m.vertices_mm.row(m.triangles(k, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    const double dn = d.dot(n), h = (a - o).dot(n);
    if (dn == 0) {
      if (h < 0) {
        t0 = 1e300, t1 = -1e300;
        return false;
      }
      continue;
    }
    if (dn < 0) {
      t0 = std::max(t0, h / dn);
    } else {
      t1 = std::min(t1, h / dn);
    }
  }
  return t0 <= t1;
}

// Every needle against convex_clip (m convex): one interval with both ends within tol, or none when the needle
// misses; a needle that only touches the solid (less than 1e-6 mm inside, or a clipping reversed by no more than
// rounding, as through a vertex from outside) may hold nothing or a point there. Returns how many needles had a
// proper interval.
int expect_convex(const TriangleMesh& m, const NeedleSet& n, const std::string& what, double tol = 1e-5) {
  std::vector<Interval> iv;
  int proper = 0, reported = 0;
  for (std::size_t k = 0; k < n.size(); ++k) {
    n.store().get(k, iv);
    double t0, t1;
    const bool clipped = convex_clip(m, n.origin(k), n.direction(k), t0, t1) || t0 <= t1 + 1e-9;
    const bool hit = clipped && t1 > 0 && t0 < n.length(k);
    t0 = std::max(t0, 0.0), t1 = std::min(t1, n.length(k));
    bool ok;
    if (hit && t1 - t0 >= 1e-6) {
      ++proper;
      ok = iv.size() == 1 && std::abs(iv[0].lo - t0) <= tol && std::abs(iv[0].hi - t1) <= tol;
    } else if (hit) {
      ok = iv.empty() || (iv.size() == 1 && std::abs(iv[0].lo - t0) <= tol && std::abs(iv[0].hi - t1) <= tol);
    } else {
      ok = iv.empty();
    }
    if (!ok && reported++ < 8)
      ADD_FAILURE() << what << " needle " << k << " from " << n.origin(k).transpose() << " along "
                    << n.direction(k).transpose() << ": ref " << (hit ? "" : "miss ") << "[" << t0 << ", " << t1
                    << "], got " << show(iv);
  }
  return proper;
}

// A convex prism over an n-gon (an ellipse with semi-axes a, b about p) whose bottom (z0) and top (z1) caps are
// fans of n long thin triangles about a centre vertex c inside it, away from the polygon's own centre: the centre
// vertex has valence n + 1 on each cap, with apex angles down to ~1 degree for n = 240.
TriangleMesh fan_prism(int n, const Eigen::Vector2d& c, const Eigen::Vector2d& p, double a, double b, double z0,
                       double z1) {
  std::vector<Eigen::Vector2d> pts = {c};
  std::vector<int> loop;
  std::vector<std::array<int, 3>> cap;
  for (int k = 0; k < n; ++k) {
    const double th = 2 * std::numbers::pi * k / n + 0.1;
    pts.push_back(p + Eigen::Vector2d(a * std::cos(th), b * std::sin(th)));
    loop.push_back(k + 1);
    cap.push_back({0, k + 1, (k + 1) % n + 1});
  }
  return prism(pts, {loop}, cap, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), z0, z1);
}

}  // namespace

TEST(MeshStock, BoxMeshEqualsFillBoxOnEveryField) {
  // Binary fractions, so that rays on the box's faces are on them exactly in double and in float; and one copy
  // far from the origin, where Embree's float coordinates would lose the part without the local origin.
  for (const Eigen::Vector3d& shift : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1e5, -2e5, 500)}) {
    const Box stock{Eigen::Vector3d(-2.5, 1.25, -10) + shift, Eigen::Vector3d(37.5, 21.25, 0) + shift};
    const std::string tag = shift.isZero() ? "near 0" : "far from 0";
    const TriangleMesh mesh = via_stl(box_mesh(stock), "box.stl");
    const MeshDexelizer dex(mesh, "box.stl");
    const Box bigger{stock.lo - Eigen::Vector3d(1.5, 2, 1), stock.hi + Eigen::Vector3d(1, 0.5, 2)};
    for (int r = 0; r < 2; ++r) {
      const Box& region = r == 0 ? stock : bigger;
      const std::string what = tag + (r == 0 ? ", region = stock" : ", region > stock");
      DexelGrid zm = make_zmap(region, 0.25), zb = make_zmap(region, 0.25);
      const MeshFillStats st = dex.fill(zm);
      fill_box(zb, stock);
      expect_identical(zm, zb, "z-map " + what);
      TriDexel tm = make_tridexel(region, 0.5), tb = make_tridexel(region, 0.5);
      dex.fill(tm.x), dex.fill(tm.y), dex.fill(tm.z);
      fill_box(tb.x, stock), fill_box(tb.y, stock), fill_box(tb.z, stock);
      expect_identical(tm.x, tb.x, "tri-dexel x " + what);
      expect_identical(tm.y, tb.y, "tri-dexel y " + what);
      expect_identical(tm.z, tb.z, "tri-dexel z " + what);
      std::printf("[ mesh     ] box %s: z-map %d x %d, %zu rays reach the mesh, %zu degenerate, %zu unresolved\n",
                  what.c_str(), zm.nu(), zm.nv(), st.rays, st.degenerate, st.unresolved);
      EXPECT_EQ(st.unresolved, 0u);

      // The same sweeps cut from both give the same floats again.
      const auto sweeps = some_sweeps(stock);
      cut(zm, sweeps), cut(zb, sweeps);
      expect_identical(zm, zb, "z-map after cutting, " + what);
      for (DexelGrid* g : {&tm.x, &tm.y, &tm.z}) cut(*g, sweeps);
      for (DexelGrid* g : {&tb.x, &tb.y, &tb.z}) cut(*g, sweeps);
      expect_identical(tm.x, tb.x, "tri-dexel x after cutting, " + what);
      expect_identical(tm.y, tb.y, "tri-dexel y after cutting, " + what);
      expect_identical(tm.z, tb.z, "tri-dexel z after cutting, " + what);
    }
    NeedleSet nm = needles_for(stock, 3000), nb = needles_for(stock, 3000);
    const MeshFillStats ns = dex.fill(nm);
    fill_box(nb, stock);
    expect_identical(nm, nb, "needles " + tag);
    EXPECT_EQ(ns.unresolved, 0u);
    const auto sweeps = some_sweeps(stock);
    cut(nm, sweeps), cut(nb, sweeps);
    expect_identical(nm, nb, "needles after cutting " + tag);
  }
}

TEST(MeshStock, OpenFlippedAndNonManifoldMeshesAreRefusedNamingTheFile) {
  const Box b{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(10, 10, 5)};
  const TriangleMesh good = box_mesh(b);
  TriangleMesh hole = good;
  hole.triangles.conservativeResize(11, 3);
  TriangleMesh flipped = good;
  std::swap(flipped.triangles(7, 0), flipped.triangles(7, 1));
  TriangleMesh fin = good;
  fin.vertices_mm.conservativeResize(9, 3);
  fin.vertices_mm.row(8) << 5, 5, 20;
  fin.triangles.conservativeResize(13, 3);
  fin.triangles.row(12) << 4, 5, 8;
  const std::pair<TriangleMesh*, std::string> cases[] = {
      {&hole, "not closed"}, {&flipped, "inconsistent orientation"}, {&fin, "not manifold"}};
  for (const auto& [mesh, problem] : cases) {
    const fs::path p = work() / "bad.stl";
    vmsim::core::write_stl_binary(p, *mesh);
    const TriangleMesh read = vmsim::core::read_stl(p);
    DexelGrid g = make_zmap(b, 1.0);
    try {
      fill_mesh(g, read, p.string());
      ADD_FAILURE() << problem << ": no error";
    } catch (const vmsim::core::Error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(p.string() + ": ", 0), 0u) << msg;
      EXPECT_NE(msg.find(problem), std::string::npos) << msg;
    }
  }
}

TEST(MeshStock, ConcaveCPrismGivesTwoIntervals) {
  // The C profile in the x-z plane: [0,3]x[0,1] + [0,1]x[1,2] + [0,3]x[2,3] (mm x 4), extruded along y.
  const double s = 4;
  const std::vector<Eigen::Vector2d> pts = {{0, 0},     {3 * s, 0},     {3 * s, s},     {s, s},
                                            {s, 2 * s}, {3 * s, 2 * s}, {3 * s, 3 * s}, {0, 3 * s}};
  const std::vector<std::array<int, 3>> cap = {{0, 1, 2}, {0, 2, 3}, {0, 3, 7}, {3, 4, 7}, {4, 5, 6}, {4, 6, 7}};
  // u = x, v = z, w = u x v = -y: the prism spans y in [-10, 0].
  const TriangleMesh c =
      via_stl(prism(pts, {{0, 1, 2, 3, 4, 5, 6, 7}}, cap, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ(), 0, 10),
              "c_prism.stl");
  ASSERT_NEAR(signed_volume(c), 7 * s * s * 10, 1e-9);  // outward orientation
  const MeshDexelizer dex(c, "c_prism.stl");
  const Box region{Eigen::Vector3d(-1, -11, -1), Eigen::Vector3d(3 * s + 1, 1, 3 * s + 1)};
  DexelGrid z = make_zmap(region, 0.5);
  const MeshFillStats st = dex.fill(z);
  std::vector<Interval> iv;
  int two = 0;
  for (int j = 0; j < z.nv(); ++j)
    for (int i = 0; i < z.nu(); ++i) {
      const Eigen::Vector3d o = z.ray_origin(i, j);
      z.intervals(i, j, iv);
      std::vector<Interval> want;
      const bool in_y = o.y() >= -10 && o.y() <= 0;
      // Closed set: rays on the faces (x = 0, 4, 12; y = -10, 0) hold what they touch. Offsets from z = -1.
      if (in_y && o.x() >= 0 && o.x() <= s) want = {{1, 1 + 3 * s}};
      if (in_y && o.x() > s && o.x() <= 3 * s) want = {{1, 1 + s}, {1 + 2 * s, 1 + 3 * s}};
      two += want.size() == 2;
      EXPECT_TRUE(same_bits(iv, want)) << "ray at " << o.transpose() << ": " << show(iv) << " want " << show(want);
    }
  EXPECT_GT(two, 100);
  EXPECT_EQ(st.unresolved, 0u);
  std::printf("[ mesh     ] C prism z-map: %zu rays, %zu degenerate\n", st.rays, st.degenerate);

  // The tri-dexel field on the same lattice (rays through every vertex, edge and face plane of the prism) against
  // the closed C worked out per axis; offsets from the region's corner (-1, -11, -1).
  TriDexel td = make_tridexel(region, 0.5);
  for (DexelGrid* g : {&td.x, &td.y, &td.z}) {
    const MeshFillStats gs = dex.fill(*g);
    EXPECT_EQ(gs.unresolved, 0u);
  }
  const auto in_profile = [&](double x, double z) {  // the closed C in the x-z plane
    return x >= 0 && x <= 3 * s && z >= 0 && z <= 3 * s && !(x > s && z > s && z < 2 * s);
  };
  for (int axis = 0; axis < 3; ++axis) {
    const DexelGrid& g = axis == 0 ? td.x : axis == 1 ? td.y : td.z;
    for (int j = 0; j < g.nv(); ++j)
      for (int i = 0; i < g.nu(); ++i) {
        const Eigen::Vector3d p = g.ray_origin(i, j);
        std::vector<Interval> want;
        const bool in_y = p.y() >= -10 && p.y() <= 0;
        if (axis == 0 && in_y && p.z() >= 0 && p.z() <= 3 * s)  // along x
          want = {{1, static_cast<float>(1 + (in_profile(3 * s, p.z()) ? 3 * s : s))}};
        if (axis == 1 && in_profile(p.x(), p.z())) want = {{1, 11}};  // along y, from y = -11
        if (axis == 2 && in_y && p.x() >= 0 && p.x() <= s) want = {{1, 1 + 3 * s}};
        if (axis == 2 && in_y && p.x() > s && p.x() <= 3 * s) want = {{1, 1 + s}, {1 + 2 * s, 1 + 3 * s}};
        g.intervals(i, j, iv);
        EXPECT_TRUE(same_bits(iv, want)) << "axis " << axis << " ray at " << p.transpose() << ": " << show(iv)
                                         << " want " << show(want);
      }
  }

  // A slanted needle crossing both arms (and the gap between them): two intervals, ends on the planes.
  const Eigen::Vector3d o(2 * s, -5, -1), d = Eigen::Vector3d(0, 0.2, 1).normalized();
  const auto got = dex.intervals(o, d, 20);
  ASSERT_EQ(got.size(), 2u) << show(got);
  EXPECT_FLOAT_EQ(got[0].lo, static_cast<float>(1 / d.z()));
  EXPECT_FLOAT_EQ(got[0].hi, static_cast<float>((1 + s) / d.z()));
  EXPECT_FLOAT_EQ(got[1].lo, static_cast<float>((1 + 2 * s) / d.z()));
  EXPECT_FLOAT_EQ(got[1].hi, static_cast<float>((1 + 3 * s) / d.z()));
}

TEST(MeshStock, FrameWithThroughHole) {
  // A square frame: outer [0,9]^2, hole [3,6]^2, in the x-y plane, extruded along z over [0, 2].
  const std::vector<Eigen::Vector2d> pts = {{0, 0}, {9, 0}, {9, 9}, {0, 9}, {3, 3}, {3, 6}, {6, 6}, {6, 3}};
  // Hole loop clockwise: 4 -> 5 -> 6 -> 7 is (3,3) (3,6) (6,6) (6,3).
  const std::vector<std::array<int, 3>> cap = {{0, 1, 7}, {0, 7, 4}, {1, 2, 6}, {1, 6, 7},
                                               {2, 3, 5}, {2, 5, 6}, {3, 0, 4}, {3, 4, 5}};
  const TriangleMesh f =
      via_stl(prism(pts, {{0, 1, 2, 3}, {4, 5, 6, 7}}, cap, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 0, 2),
              "frame.stl");
  ASSERT_NEAR(signed_volume(f), (81 - 9) * 2, 1e-9);
  const MeshDexelizer dex(f, "frame.stl");
  // Rays along x at y = 4.5 cross the frame twice; along z through the hole, nothing; through the ring, [0, 2].
  for (double z : {0.0, 0.5, 1.0, 2.0}) {
    const auto iv = dex.intervals(Eigen::Vector3d(-1, 4.5, z), Eigen::Vector3d::UnitX(), 11);
    EXPECT_TRUE(same_bits(iv, {{1, 4}, {7, 10}})) << "z = " << z << ": " << show(iv);
  }
  EXPECT_TRUE(dex.intervals(Eigen::Vector3d(4.5, 4.5, -1), Eigen::Vector3d::UnitZ(), 4).empty());
  EXPECT_TRUE(same_bits(dex.intervals(Eigen::Vector3d(1.5, 4.5, -1), Eigen::Vector3d::UnitZ(), 4), {{1, 3}}));
  // Through the ring's triangulation diagonals (0,0)-(3,3) etc.: shared edges of two cap triangles.
  EXPECT_TRUE(same_bits(dex.intervals(Eigen::Vector3d(1.5, 1.5, -1), Eigen::Vector3d::UnitZ(), 4), {{1, 3}}));
  EXPECT_TRUE(same_bits(dex.intervals(Eigen::Vector3d(3, 3, -1), Eigen::Vector3d::UnitZ(), 4), {{1, 3}}));
  // Along the hole's wall (x = 3, inside the wall's plane): the closed set holds the wall.
  EXPECT_TRUE(same_bits(dex.intervals(Eigen::Vector3d(3, 4.5, -1), Eigen::Vector3d::UnitZ(), 4), {{1, 3}}));
}

TEST(MeshStock, RaysThroughVerticesAndEdgesGetTheRightParity) {
  // Octahedron |x| + |y| + |z| <= 10: every ray below passes through vertices or edges.
  TriangleMesh o;
  o.vertices_mm.resize(6, 3);
  o.vertices_mm << 10, 0, 0, -10, 0, 0, 0, 10, 0, 0, -10, 0, 0, 0, 10, 0, 0, -10;
  o.triangles.resize(8, 3);
  int t = 0;
  for (int sx : {0, 1})
    for (int sy : {2, 3})
      for (int sz : {4, 5}) {
        // Outward: counter-clockwise when the signs' parity is even.
        const bool flip = ((sx == 1) + (sy == 3) + (sz == 5)) % 2 == 1;
        if (flip)
          o.triangles.row(t++) << sx, sz, sy;
        else
          o.triangles.row(t++) << sx, sy, sz;
      }
  o = via_stl(o, "octahedron.stl");
  ASSERT_NEAR(signed_volume(o), 4.0 / 3 * 1000, 1e-9);
  const MeshDexelizer dex(o, "octahedron.stl");
  const Eigen::Vector3d Z = Eigen::Vector3d::UnitZ();
  // Through both apexes (4 triangles meet at each).
  EXPECT_TRUE(same_bits(dex.intervals({0, 0, -20}, Z, 40), {{10, 30}})) << show(dex.intervals({0, 0, -20}, Z, 40));
  // Through the edges (10,0,0)-(0,0,+-10), shared by two faces each.
  EXPECT_TRUE(same_bits(dex.intervals({5, 0, -20}, Z, 40), {{15, 25}})) << show(dex.intervals({5, 0, -20}, Z, 40));
  // Along x through the vertices (+-10, 0, 0).
  EXPECT_TRUE(same_bits(dex.intervals({-20, 0, 0}, Eigen::Vector3d::UnitX(), 40), {{10, 30}}));
  // Touching the silhouette edge (10,0,0)-(0,10,0) at (5,5,0) from below and the vertex (10,0,0): one point.
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(5, 5, -20), Eigen::Vector3d(10, 0, -20)}) {
    const auto iv = dex.intervals(p, Z, 40);
    ASSERT_EQ(iv.size(), 1u) << p.transpose() << ": " << show(iv);
    EXPECT_NEAR(iv[0].lo, 20, 1e-5);
    EXPECT_NEAR(iv[0].hi, 20, 1e-5);
  }
  // Just outside the vertex and the edge by 1e-3: nothing.
  EXPECT_TRUE(dex.intervals({10.001, 0, -20}, Z, 40).empty());
  EXPECT_TRUE(dex.intervals({5.001, 5, -20}, Z, 40).empty());
  // A z-map over the octahedron on a grid through its vertices and edges: every ray against |z| <= 10 - |x| - |y|.
  DexelGrid g = make_zmap(Box{Eigen::Vector3d(-12, -12, -12), Eigen::Vector3d(12, 12, 12)}, 0.5);
  const MeshFillStats st = dex.fill(g);
  std::vector<Interval> iv;
  for (int j = 0; j < g.nv(); ++j)
    for (int i = 0; i < g.nu(); ++i) {
      const Eigen::Vector3d p = g.ray_origin(i, j);
      const double h = 10 - std::abs(p.x()) - std::abs(p.y());
      g.intervals(i, j, iv);
      if (h < 0) {
        EXPECT_TRUE(iv.empty()) << p.transpose() << ": " << show(iv);
      } else {
        ASSERT_EQ(iv.size(), 1u) << p.transpose();
        EXPECT_NEAR(iv[0].lo, 12 - h, 2e-6) << p.transpose();
        EXPECT_NEAR(iv[0].hi, 12 + h, 2e-6) << p.transpose();
      }
    }
  EXPECT_EQ(st.unresolved, 0u);
  std::printf("[ mesh     ] octahedron z-map: %zu rays, %zu degenerate\n", st.rays, st.degenerate);
}

// An icosphere (convex: the intersection of its faces' half-spaces), rotated off the axes and placed far from the
// origin, against the half-space clipping of each ray in double. Needles aimed exactly at its vertices and edge
// midpoints exercise the symbolic resolution of degenerate rays in every direction.
TEST(MeshStock, ConvexPolyhedronAgainstHalfSpaceClipping) {
  const double phi = (1 + std::sqrt(5.0)) / 2;
  std::vector<Eigen::Vector3d> v = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                                    {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                                    {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < 2; ++level) {  // each level splits every face in four, midpoints on the sphere
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized() * v[0].norm());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> g;
    for (const auto& t : f) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      g.push_back({t[0], ab, ca}), g.push_back({t[1], bc, ab}), g.push_back({t[2], ca, bc}), g.push_back({ab, bc, ca});
    }
    f = g;
  }
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d T(1e4, -3e3, 250);
  TriangleMesh m;
  m.vertices_mm.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t k = 0; k < v.size(); ++k)
    m.vertices_mm.row(static_cast<Eigen::Index>(k)) = (R * (v[k] * 5) + T).transpose();
  m.triangles.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (std::size_t k = 0; k < f.size(); ++k) m.triangles.row(static_cast<Eigen::Index>(k)) << f[k][0], f[k][1], f[k][2];
  ASSERT_GT(signed_volume(m), 0);
  const MeshDexelizer dex(m, "icosphere");

  // Reference: [max entering t, min leaving t] over the face planes.
  const auto reference = [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t0, double& t1) {
    t0 = -1e300, t1 = 1e300;
    for (Eigen::Index k = 0; k < m.triangles.rows(); ++k) {
      const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(k, 0)), b = m.vertices_mm.row(m.triangles(k, 1)),
                            c = m.vertices_mm.row(m.triangles(k, 2));
      const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
      const double dn = d.dot(n), h = (a - o).dot(n);
      if (dn == 0) {
        if (h < 0) return false;
        continue;
      }
      (dn < 0 ? t0 : t1) = dn < 0 ? std::max(t0, h / dn) : std::min(t1, h / dn);
    }
    return t0 <= t1;
  };
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  const auto add = [&](const Eigen::Vector3d& through, Eigen::Vector3d dir) {
    dir.normalize();
    o.push_back(through - 20 * dir);
    d.push_back(dir);
    len.push_back(40);
  };
  for (Eigen::Index k = 0; k < m.vertices_mm.rows(); ++k)  // through every vertex, 3 directions each
    for (int r = 0; r < 3; ++r) add(m.vertices_mm.row(k).transpose(), Eigen::Vector3d(u(rng), u(rng), u(rng)));
  for (Eigen::Index k = 0; k < m.triangles.rows(); ++k)  // through every edge midpoint
    for (int e = 0; e < 3; ++e)
      add(0.5 * (m.vertices_mm.row(m.triangles(k, e)) + m.vertices_mm.row(m.triangles(k, (e + 1) % 3))).transpose(),
          Eigen::Vector3d(u(rng), u(rng), u(rng)));
  for (int k = 0; k < 5000; ++k)
    add(T + 6 * Eigen::Vector3d(u(rng), u(rng), u(rng)), Eigen::Vector3d(u(rng), u(rng), u(rng)));
  NeedleSet needles(o, d, len);
  const MeshFillStats st = dex.fill(needles);
  std::vector<Interval> iv;
  int checked = 0, touching = 0;
  double worst = 0;
  for (std::size_t k = 0; k < needles.size(); ++k) {
    needles.store().get(k, iv);
    double t0, t1;
    // Through a vertex or along an edge the clipping's rounding can leave t0 a hair above t1: a touch too.
    const bool hit = reference(needles.origin(k), needles.direction(k), t0, t1) || t0 <= t1 + 1e-9;
    if (hit && t1 - t0 < 1e-6) {  // a touch: within float resolution of the surface either answer is right
      ++touching;
      if (!iv.empty()) {
        EXPECT_NEAR(iv[0].lo, t0, 1e-5);
      }
      continue;
    }
    ++checked;
    if (!hit) {
      EXPECT_TRUE(iv.empty()) << "needle " << k << ": " << show(iv);
      continue;
    }
    ASSERT_EQ(iv.size(), 1u) << "needle " << k << " ref [" << t0 << ", " << t1 << "]: " << show(iv);
    const double err = std::max(std::abs(iv[0].lo - t0), std::abs(iv[0].hi - t1));
    if (err > 1e-5) ADD_FAILURE() << "needle " << k << " ref [" << t0 << ", " << t1 << "]: " << show(iv);
    worst = std::max(worst, err);
  }
  EXPECT_LT(worst, 1e-5);  // float storage of offsets up to 40 mm: half an ulp is 1.9e-6 mm
  EXPECT_EQ(st.unresolved, 0u);
  std::printf(
      "[ mesh     ] icosphere (%ld triangles) far from 0: %d needles checked, %d touching, %zu degenerate, "
      "worst |dt| %.2e mm\n",
      static_cast<long>(m.triangles.rows()), checked, touching, st.degenerate, worst);
}

TEST(MeshStock, HeightfieldMeshThroughItsOwnNodes) {
  // A closed height-field solid (removal/surface) sampled by a z-map whose rays pass through every vertex of the
  // top surface: the top read back equals the node heights.
  vmsim::core::HeightGrid hg;
  hg.x0_mm = 10;
  hg.y0_mm = -5;
  hg.dx_mm = hg.dy_mm = 0.5;
  hg.z_mm.resize(41, 61);
  for (Eigen::Index j = 0; j < hg.ny(); ++j)
    for (Eigen::Index i = 0; i < hg.nx(); ++i) hg.z_mm(j, i) = 3 + std::sin(0.3 * i) * std::cos(0.2 * j);
  const TriangleMesh m = heightfield_mesh(hg, -2);
  const MeshDexelizer dex(m, "heightfield");
  const Box region{Eigen::Vector3d(hg.x0_mm, hg.y0_mm, -3), Eigen::Vector3d(hg.x(hg.nx() - 1), hg.y(hg.ny() - 1), 5)};
  DexelGrid g = make_zmap(region, 0.5);
  const MeshFillStats st = dex.fill(g);
  ASSERT_EQ(g.nu(), hg.nx());
  ASSERT_EQ(g.nv(), hg.ny());
  std::vector<Interval> iv;
  for (int j = 0; j < g.nv(); ++j)
    for (int i = 0; i < g.nu(); ++i) {
      g.intervals(i, j, iv);
      ASSERT_EQ(iv.size(), 1u) << i << " " << j << ": " << show(iv);
      EXPECT_EQ(iv[0].lo, 1.0f);
      EXPECT_NEAR(iv[0].hi, hg.z_mm(j, i) + 3, 1e-6) << i << " " << j;
    }
  EXPECT_EQ(st.unresolved, 0u);
  EXPECT_EQ(st.degenerate, st.rays);  // every ray is on a vertex
}

// A vertex shared by many long thin triangles (a fan, as CAD exports and heightfield_mesh's bottom have): rays
// exactly through the centre, exactly or nearly on the fan's edges, and at tiny offsets from the centre (down to
// far below the tolerance; finite shifted re-casts stayed degenerate there) all enter through the bottom cap and
// leave through the top, with no unresolved ray. Vertical rays get the caps' planes exactly; oblique ones are checked
// against half-space clipping (the prism is convex).
TEST(MeshStock, RaysThroughTheCentreOfAFanOfThinTriangles) {
  const int n = 240;
  const double z0 = -2.5, z1 = 4.25, oz = -5;
  for (const double scale : {1.0, 1e-3}) {  // also a fan 50 um across: tau is then far below the part's features
    const TriangleMesh m = via_stl(fan_prism(n, scale * Eigen::Vector2d(0.3183098861837907, -0.2718281828459045),
                                             scale * Eigen::Vector2d(-6.1, 2.3), scale * 40, scale * 15, z0, z1),
                                   "fan_prism.stl");
    ASSERT_GT(signed_volume(m), 0);
    const MeshDexelizer dex(m, "fan_prism.stl");
    const double tau = dex.tolerance_mm();
    // The STL round trip renumbers the vertices (and rounds them to float): the centres are the cap vertices
    // nearest the nominal one, the rest of the bottom cap is the fan's rim.
    const Eigen::Vector2d nominal = scale * Eigen::Vector2d(0.3183098861837907, -0.2718281828459045);
    Eigen::Vector3d cb(1e300, 0, 0), ct(1e300, 0, 0);
    std::vector<Eigen::Vector2d> rim;
    for (Eigen::Index k = 0; k < m.vertices_mm.rows(); ++k) {
      const Eigen::Vector3d p = m.vertices_mm.row(k).transpose();
      Eigen::Vector3d& best = p.z() == z0 ? cb : ct;
      if ((p.head<2>() - nominal).norm() < (best.head<2>() - nominal).norm()) best = p;
      if (p.z() == z0) rim.push_back(p.head<2>());
    }
    ASSERT_EQ(cb.head<2>(), ct.head<2>());
    ASSERT_EQ(rim.size(), static_cast<std::size_t>(n + 1));
    const Eigen::Vector2d c = cb.head<2>();
    rim.erase(std::find(rim.begin(), rim.end(), c));
    const std::string tag = "scale " + std::to_string(scale) + ": ";

    // Vertical needles (up from z = oz and down from z = 10), through points in the plane.
    std::vector<Eigen::Vector2d> at = {c};
    for (int k = 0; k < n; k += 7) {  // on (or within rounding of) the fan's edges, near the centre
      const Eigen::Vector2d e = rim[static_cast<std::size_t>(k)] - c;
      for (double s : {0x1p-40, 0x1p-30, 0x1p-20, 1e-9, 1e-7, 1e-5, 1e-3}) at.push_back(c + s * e);
    }
    for (double rho : {1e-300, 1e-15, 1e-12, 1e-10, 1e-8, 0.25 * tau, tau, 3 * tau, 16 * tau, 40 * tau, 1000 * tau})
      for (int q = 0; q < 16; ++q) {
        const double phi = q * std::numbers::pi / 8 + (q % 3) * 1e-9;
        at.push_back(c + rho * Eigen::Vector2d(std::cos(phi), std::sin(phi)));
      }
    std::vector<Eigen::Vector3d> o, d;
    std::vector<double> len;
    for (const Eigen::Vector2d& p : at) {
      o.emplace_back(p.x(), p.y(), oz), d.push_back(Eigen::Vector3d::UnitZ()), len.push_back(15);
      o.emplace_back(p.x(), p.y(), 10), d.push_back(-Eigen::Vector3d::UnitZ()), len.push_back(15);
    }
    NeedleSet vertical(o, d, len);
    MeshFillStats st = dex.fill(vertical);
    EXPECT_EQ(st.unresolved, 0u) << tag;
    std::vector<Interval> iv;
    for (std::size_t k = 0; k < vertical.size(); ++k) {
      vertical.store().get(k, iv);
      const std::vector<Interval> want = {k % 2 == 0
                                              ? Interval{static_cast<float>(z0 - oz), static_cast<float>(z1 - oz)}
                                              : Interval{static_cast<float>(10 - z1), static_cast<float>(10 - z0)}};
      EXPECT_TRUE(same_bits(iv, want)) << tag << "needle " << k << " at " << vertical.origin(k).transpose() << ": "
                                       << show(iv) << " want " << show(want);
    }
    std::printf("[ mesh     ] fan of %d (scale %g): %zu vertical needles, %zu degenerate, %zu unresolved\n", n, scale,
                st.rays, st.degenerate, st.unresolved);

    // Z-maps whose node (8, 8) is the centre, at spacings from 2^-30 mm (every ray within tau of the centre) to
    // 2^-6 mm: c - 8 h and c - 8 h + 8 h are exact for these powers of two.
    for (int e : {30, 24, 20, 14, 6}) {
      const double h = std::ldexp(scale, -e);
      const Box region{Eigen::Vector3d(c.x() - 8 * h, c.y() - 8 * h, oz),
                       Eigen::Vector3d(c.x() + 8 * h, c.y() + 8 * h, 10)};
      DexelGrid g = make_zmap(region, h);
      ASSERT_EQ(g.ray_origin(8, 8).x(), c.x());
      ASSERT_EQ(g.ray_origin(8, 8).y(), c.y());
      st = dex.fill(g);
      EXPECT_EQ(st.unresolved, 0u) << tag << "h = 2^-" << e;
      for (int j = 0; j < g.nv(); ++j)
        for (int i = 0; i < g.nu(); ++i) {
          g.intervals(i, j, iv);
          EXPECT_TRUE(same_bits(iv, {{static_cast<float>(z0 - oz), static_cast<float>(z1 - oz)}}))
              << tag << "h = 2^-" << e << ", ray (" << i << ", " << j << "): " << show(iv);
        }
    }

    // Oblique needles through both centres and through points on the fan's edges near them, against clipping.
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    o.clear(), d.clear(), len.clear();
    for (int k = 0; k < 400; ++k) {
      Eigen::Vector3d through = k % 2 ? cb : ct;
      if (k % 4 >= 2) {
        const Eigen::Vector2d e = rim[static_cast<std::size_t>(k % n)] - c;
        through.head<2>() = c + (k % 8 >= 4 ? 1e-9 : 1e-4) * e;
      }
      Eigen::Vector3d dir(u(rng), u(rng), u(rng));
      if (k % 5 == 0) dir.z() = 10 * dir.z();  // some steep ones
      dir.normalize();
      o.push_back(through - 20 * scale * dir), d.push_back(dir), len.push_back(40 * scale);
    }
    // And needles lying in the caps' planes through the centres (along the fan's edges and between them): the
    // closed set holds the chord of the cap.
    for (int k = 0; k < 60; ++k) {
      const Eigen::Vector3d through = k % 2 ? cb : ct;
      const Eigen::Vector2d e = k % 4 >= 2 ? rim[static_cast<std::size_t>(k % n)] - c : Eigen::Vector2d(u(rng), u(rng));
      const Eigen::Vector3d dir = Eigen::Vector3d(e.x(), e.y(), 0).normalized();
      o.push_back(through - 60 * scale * dir), d.push_back(dir), len.push_back(120 * scale);
    }
    NeedleSet oblique(o, d, len);
    st = dex.fill(oblique);
    EXPECT_EQ(st.unresolved, 0u) << tag;
    EXPECT_GT(expect_convex(m, oblique, tag + "oblique"), 400);
  }
}

// Vertices shared by many thin triangles that do not lie in one plane: the apices of a double pyramid over a
// 256-gon. Rays through both apices (any shifted ray lands in one of many differently inclined thin triangles),
// along the edges into them and at tiny offsets, vertical and oblique, against clipping.
TEST(MeshStock, RaysThroughTheApicesOfADoublePyramid) {
  const int n = 256;
  const Eigen::Vector2d c(0.3183098861837907, -0.2718281828459045), p(-6.1, 2.3);
  TriangleMesh m;
  m.vertices_mm.resize(n + 2, 3);
  for (int k = 0; k < n; ++k) {
    const double th = 2 * std::numbers::pi * k / n + 0.1;
    m.vertices_mm.row(k) << p.x() + 40 * std::cos(th), p.y() + 15 * std::sin(th), 0;
  }
  m.vertices_mm.row(n) << c.x(), c.y(), 7.5;     // top apex
  m.vertices_mm.row(n + 1) << c.x(), c.y(), -5;  // bottom apex
  m.triangles.resize(2 * n, 3);
  for (int k = 0; k < n; ++k) {
    m.triangles.row(2 * k) << n, k, (k + 1) % n;
    m.triangles.row(2 * k + 1) << n + 1, (k + 1) % n, k;
  }
  ASSERT_GT(signed_volume(m), 0);
  const MeshDexelizer dex(m, "double pyramid");
  const double tau = dex.tolerance_mm();
  const Eigen::Vector3d top = m.vertices_mm.row(n).transpose(), bottom = m.vertices_mm.row(n + 1).transpose();
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  const auto add = [&](const Eigen::Vector3d& through, const Eigen::Vector3d& dir) {
    o.push_back(through - 30 * dir.normalized()), d.push_back(dir.normalized()), len.push_back(60);
  };
  for (const Eigen::Vector3d& apex : {top, bottom}) {
    add(apex, Eigen::Vector3d::UnitZ());
    add(apex, -Eigen::Vector3d::UnitZ());
    for (int k = 0; k < n; k += 5) {  // through points on (or within rounding of) the edges into the apex
      const Eigen::Vector3d e = m.vertices_mm.row(k).transpose() - apex;
      for (double s : {1e-9, 1e-6, 1e-3}) {
        add(apex + s * e, Eigen::Vector3d::UnitZ());
        add(apex + s * e, Eigen::Vector3d(0.2 * u(rng), 0.2 * u(rng), 1));
      }
    }
    for (double rho : {1e-15, 1e-10, 0.25 * tau, tau, 10 * tau})
      for (int q = 0; q < 12; ++q)
        add(apex + rho * Eigen::Vector3d(std::cos(q * 0.5236), std::sin(q * 0.5236), 0), Eigen::Vector3d::UnitZ());
    for (int k = 0; k < 200; ++k) add(apex, Eigen::Vector3d(u(rng), u(rng), u(rng)));  // through the apex
  }
  NeedleSet needles(o, d, len);
  const MeshFillStats st = dex.fill(needles);
  EXPECT_EQ(st.unresolved, 0u);
  const int proper = expect_convex(m, needles, "double pyramid");
  EXPECT_GT(proper, 400);
  std::printf("[ mesh     ] double pyramid over a %d-gon: %zu needles, %d through the solid, %zu degenerate\n", n,
              needles.size(), proper, st.degenerate);
  // A z-map whose node (8, 8) is on both apices, at 2^-24 mm: every ray within tau of them.
  const double h = 0x1p-24;
  DexelGrid g = make_zmap(
      Box{Eigen::Vector3d(c.x() - 8 * h, c.y() - 8 * h, -10), Eigen::Vector3d(c.x() + 8 * h, c.y() + 8 * h, 10)}, h);
  ASSERT_EQ(g.ray_origin(8, 8).x(), c.x());
  ASSERT_EQ(g.ray_origin(8, 8).y(), c.y());
  const MeshFillStats gs = dex.fill(g);
  EXPECT_EQ(gs.unresolved, 0u);
  std::vector<Interval> iv;
  for (int j = 0; j < g.nv(); ++j)
    for (int i = 0; i < g.nu(); ++i) {
      g.intervals(i, j, iv);
      double t0, t1;
      ASSERT_TRUE(convex_clip(m, g.ray_origin(i, j), Eigen::Vector3d::UnitZ(), t0, t1));
      ASSERT_EQ(iv.size(), 1u) << i << " " << j << ": " << show(iv);
      EXPECT_NEAR(iv[0].lo, t0, 1e-5) << i << " " << j;
      EXPECT_NEAR(iv[0].hi, t1, 1e-5) << i << " " << j;
    }
}

// heightfield_mesh's bottom is a fan of 2 (nx + ny) - 4 triangles about an off-lattice centre: z-maps with a node
// exactly on that centre, and needles through it and along the fan's edges, get the solid between the bottom and
// the top surface.
TEST(MeshStock, HeightfieldBottomFanCentre) {
  vmsim::core::HeightGrid hg;
  hg.x0_mm = 10;
  hg.y0_mm = -5;
  hg.dx_mm = 0.5;
  hg.dy_mm = 0.75;
  hg.z_mm.resize(61, 41);
  for (Eigen::Index j = 0; j < hg.ny(); ++j)
    for (Eigen::Index i = 0; i < hg.nx(); ++i) hg.z_mm(j, i) = 3 + std::sin(0.3 * i) * std::cos(0.2 * j);
  const double bottom = -2, oz = -3;
  const TriangleMesh m = heightfield_mesh(hg, bottom);
  const Eigen::Index nx = hg.nx(), ny = hg.ny();
  const Eigen::Vector3d centre = m.vertices_mm.row(m.vertices_mm.rows() - 1).transpose();
  ASSERT_EQ(centre.x(), hg.x((nx - 1) / 2) + 0.3183098861837907 * hg.dx_mm);
  ASSERT_EQ(centre.y(), hg.y((ny - 1) / 2) + 0.2718281828459045 * hg.dy_mm);
  ASSERT_EQ(centre.z(), bottom);
  const MeshDexelizer dex(m, "heightfield");
  // The top surface over (x, y): the cell's triangle (a, b, c) or (a, c, e) as heightfield_mesh splits it.
  const auto top = [&](double x, double y) {
    const double fx = (x - hg.x0_mm) / hg.dx_mm, fy = (y - hg.y0_mm) / hg.dy_mm;
    const Eigen::Index i = std::clamp<Eigen::Index>(static_cast<Eigen::Index>(std::floor(fx)), 0, nx - 2);
    const Eigen::Index j = std::clamp<Eigen::Index>(static_cast<Eigen::Index>(std::floor(fy)), 0, ny - 2);
    const double u = fx - i, v = fy - j;
    const double za = hg.z_mm(j, i), zb = hg.z_mm(j, i + 1), zc = hg.z_mm(j + 1, i + 1), ze = hg.z_mm(j + 1, i);
    return u >= v ? za + u * (zb - za) + v * (zc - zb) : za + v * (ze - za) + u * (zc - ze);
  };
  std::vector<Interval> iv;
  for (int e : {40, 30, 20, 12, 4}) {  // spacing 2^-e mm: c - 16 h and back are exact
    const double h = std::ldexp(1.0, -e);
    const Box region{Eigen::Vector3d(centre.x() - 16 * h, centre.y() - 16 * h, oz),
                     Eigen::Vector3d(centre.x() + 16 * h, centre.y() + 16 * h, 6)};
    DexelGrid g = make_zmap(region, h);
    ASSERT_EQ(g.ray_origin(16, 16).x(), centre.x());
    ASSERT_EQ(g.ray_origin(16, 16).y(), centre.y());
    const MeshFillStats st = dex.fill(g);
    EXPECT_EQ(st.unresolved, 0u) << "h = 2^-" << e;
    for (int j = 0; j < g.nv(); ++j)
      for (int i = 0; i < g.nu(); ++i) {
        const Eigen::Vector3d p = g.ray_origin(i, j);
        g.intervals(i, j, iv);
        ASSERT_EQ(iv.size(), 1u) << "h = 2^-" << e << ", ray (" << i << ", " << j << "): " << show(iv);
        EXPECT_EQ(iv[0].lo, static_cast<float>(bottom - oz)) << "h = 2^-" << e << ", ray (" << i << ", " << j << ")";
        EXPECT_NEAR(iv[0].hi, top(p.x(), p.y()) - oz, 1e-5) << "h = 2^-" << e << ", ray (" << i << ", " << j << ")";
      }
    std::printf(
        "[ mesh     ] heightfield bottom fan, z-map at 2^-%d mm about its centre: %zu degenerate, %zu "
        "unresolved\n",
        e, st.degenerate, st.unresolved);
  }
  // Needles through the centre and along the fan's edges near it, vertical and oblique (steep enough to leave
  // through the top surface once: the top's slope is below 1); the top end found by bisection on the surface.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  std::vector<double> want_lo;
  const Eigen::Index base = m.vertices_mm.rows() - 1 - 2 * (nx + ny - 2);  // the bottom ring's first node
  for (int k = 0; k < 600; ++k) {
    Eigen::Vector3d through = centre;
    if (k % 3 > 0) {
      const Eigen::Vector3d r = m.vertices_mm.row(base + k % (2 * (nx + ny - 2))).transpose();
      through = centre + (k % 3 == 1 ? 1e-9 : 1e-5) * (r - centre);
    }
    Eigen::Vector3d dir(0, 0, 1);
    if (k % 4 > 0) dir = Eigen::Vector3d(0.3 * u(rng), 0.3 * u(rng), 1).normalized();
    o.push_back(through - 5 * dir), d.push_back(dir), len.push_back(15);
    want_lo.push_back(5);
  }
  NeedleSet needles(o, d, len);
  const MeshFillStats st = dex.fill(needles);
  EXPECT_EQ(st.unresolved, 0u);
  for (std::size_t k = 0; k < needles.size(); ++k) {
    needles.store().get(k, iv);
    double a = 5, b = 15;  // the ray leaves the solid through the top between these
    for (int it = 0; it < 100; ++it) {
      const double t = 0.5 * (a + b);
      const Eigen::Vector3d p = o[k] + t * d[k];
      (p.z() < top(p.x(), p.y()) ? a : b) = t;
    }
    ASSERT_EQ(iv.size(), 1u) << "needle " << k << ": " << show(iv);
    EXPECT_NEAR(iv[0].lo, want_lo[k], 1e-5) << "needle " << k;
    EXPECT_NEAR(iv[0].hi, a, 1e-5) << "needle " << k;
  }
  std::printf("[ mesh     ] heightfield bottom fan, needles through its centre: %zu degenerate, %zu unresolved\n",
              st.degenerate, st.unresolved);
}

TEST(MeshStock, ResultDoesNotDependOnThreadCount) {
  vmsim::core::HeightGrid hg;
  hg.dx_mm = hg.dy_mm = 1.3;
  hg.z_mm.resize(30, 30);
  for (Eigen::Index j = 0; j < 30; ++j)
    for (Eigen::Index i = 0; i < 30; ++i) hg.z_mm(j, i) = std::cos(0.4 * i + 0.1 * j);
  const TriangleMesh m = heightfield_mesh(hg, -3);
  const MeshDexelizer dex(m);
  const Box region{Eigen::Vector3d(-1, -1, -4), Eigen::Vector3d(40, 40, 2)};
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  DexelGrid a = make_zmap(region, 0.1);
  dex.fill(a);
  omp_set_num_threads(std::max(2, threads));
  DexelGrid b = make_zmap(region, 0.1);
  dex.fill(b);
  omp_set_num_threads(threads);
  expect_identical(a, b, "1 thread vs several");
}

TEST(MeshStock, TimingZmap1000x1000From10kTriangles) {
  // The figure the report quotes: a 1000 x 1000 z-map filled from a ~10k-triangle closed mesh.
  vmsim::core::HeightGrid hg;
  hg.dx_mm = hg.dy_mm = 100.0 / 50;  // 51 x 51 nodes: 2 x 2 x 50 x 50 top and bottom + 400 wall triangles
  hg.z_mm.resize(51, 51);
  for (Eigen::Index j = 0; j < 51; ++j)
    for (Eigen::Index i = 0; i < 51; ++i) hg.z_mm(j, i) = 20 + 3 * std::sin(0.29 * i) * std::cos(0.23 * j);
  const TriangleMesh m = heightfield_mesh(hg, 0);
  const auto t0 = std::chrono::steady_clock::now();
  const MeshDexelizer dex(m);
  const auto t1 = std::chrono::steady_clock::now();
  std::printf("[ mesh     ] %ld triangles: check + BVH %.3f s\n", static_cast<long>(m.triangles.rows()),
              std::chrono::duration<double>(t1 - t0).count());
  // On the mesh's lattice every 20th row and column of rays runs along its edges (and every 20th diagonal along
  // the cells' diagonals); shifted off it, no ray does.
  for (const Eigen::Vector2d& off : {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.037, 0.061)}) {
    const Box region{Eigen::Vector3d(off.x(), off.y(), -1), Eigen::Vector3d(99.9 + off.x(), 99.9 + off.y(), 30)};
    DexelGrid g = make_zmap(region, 0.1);
    const auto t2 = std::chrono::steady_clock::now();
    const MeshFillStats st = dex.fill(g);
    const auto t3 = std::chrono::steady_clock::now();
    std::printf(
        "[ mesh     ] z-map %d x %d at offset (%.3f, %.3f) filled in %.3f s with %d threads (%zu rays, %zu "
        "degenerate)\n",
        g.nu(), g.nv(), off.x(), off.y(), std::chrono::duration<double>(t3 - t2).count(), omp_get_max_threads(),
        st.rays, st.degenerate);
    EXPECT_EQ(g.nu(), 1000);
    EXPECT_EQ(g.nv(), 1000);
    EXPECT_EQ(st.unresolved, 0u);
  }
}
