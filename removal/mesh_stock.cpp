// Triangle-mesh stocks to dexels with Embree 3 (see mesh_stock.hpp for the method in brief).
//
// Why an intersection filter, not repeated rtcIntersect1 calls: the filter sees every triangle the ray crosses in
// one BVH traversal (it records the primitive and rejects the hit, so Embree keeps going), whereas stepping tnear
// past each hit restarts the traversal once per crossing and, worse, skips or repeats crossings that share one t
// (a ray through a shared edge or vertex): exactly the cases that need care. The filter may see a primitive
// twice (Embree says so for spatial-split builds), so the primitives are de-duplicated.
//
// Why t is recomputed in double: Embree's t is a float relative to the ray's float origin, ~1e-7 of the mesh size
// off; the plane intersection on the original double vertices is exact to double rounding and, for faces normal
// to an axis, performs the very operations fill_box's slab test does ((a_i - o_i) / d_i), hence equal bits.
//
// Shared edges and vertices: Embree's robust triangle test is watertight on the float mesh (adjacent triangles
// share vertex indices, and its edge tests are exact negations of each other across a shared edge), so a ray
// crossing the float surface is reported by at least one of the triangles at an edge, but a ray through an edge
// may be reported by both and a ray through a vertex by any subset of its fan. Rather than guess which duplicates
// to drop (a ray touching a silhouette edge legitimately crosses twice at one t), such rays are detected in double
// (crossing within tau of an edge line, face parallel to the ray, odd crossing count) and resolved exactly by a
// symbolic perturbation (resolve()): an exact point-in-triangle test in the plane normal to the ray, with ties on
// edges and vertices broken by shifting the ray infinitesimally (Simulation of Simplicity), one shift into each
// quadrant around it, the union of the four results kept.
//
// Why not shifted re-casts (what this did before): four rays shifted by delta = 16 tau, each mapped back onto the
// original through the planes of the triangles it crossed. Around a vertex shared by many long thin triangles (a
// fan: heightfield_mesh's bottom, CAD exports) that fails: with apex angles of ~1 degree, a ray within ~60 tau of
// the centre stays within tau of some fan edge line, so every shifted ray was degenerate again (unresolved, then
// a lenient cast that dropped the fan's near-edge crossings: no material at all), and the crossings of rays that
// did resolve were mapped back through whichever thin triangles they happened to land in. No finite shift is
// right for every valence; the symbolic shift is infinitesimal, exact and consistent across shared edges, so the
// fan contributes exactly one crossing whatever its valence.
//
// Rays lying in the plane of a BVH box face: Embree turns a zero direction component into a tiny positive one,
// so a ray exactly on a box's upper face (a vertex coordinate) leaves the box at t = 0 and sees none of its
// triangles (found with a ray along the top face of a frame). Such rays are cast again one float below; see cast().
//
// Residual risks:
//   - A ray within float resolution (~1e-7 x mesh size) of a tangency (touching a vertex or silhouette edge from
//     outside, lying in a face's plane) at coordinates that are not exact in float may be missed by Embree
//     altogether; it then gets the open-set answer (nothing at the touching point or face) instead of the closed
//     one. Axis-aligned rays at a vertex's own double coordinates (a grid on the stock's bounding box, a lattice
//     through the mesh's nodes) are detected: there Embree's edge tests come out exactly 0, which counts as a hit.
//   - A degenerate ray sees only triangles Embree reported plus those reached from them through vertices and
//     edges within tau of the ray; a triangle the ray crosses exactly but that is neither (float error beyond
//     tau: not for a mesh whose coordinates fit in float to ~1e-7 of its size) leaves an odd count in every
//     shift: the ray is counted as unresolved and gets the lenient best effort.
//   - Projection onto the plane normal to the ray rounds (exact for rays along an axis, e.g. every grid): for an
//     oblique ray within ~1e-16 x distance of an edge, which side it passes is decided on the rounded projection,
//     consistently for all triangles at that edge. t of a crossing at a face nearly parallel to the ray is the
//     plane intersection, as ill-conditioned as the geometry (kept within the triangle's extent along the ray).
//   - A self-intersecting mesh (check_closed does not look for intersections) gives crossing-parity (XOR) results.
#include "removal/mesh_stock.hpp"

#include "core/error.hpp"
#include "core/stl.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace vmsim::removal {

namespace {

constexpr double kTauRel = 1e-6;      // tau / mesh size: ~10x Embree's float error on a mesh centred at 0
constexpr double kMarginPerTau = 65;  // the cast span's margin beyond the mesh's box, well beyond Embree's error
constexpr double kMaxCoordMm = 1e9;   // as core/stl.cpp: keeps float conversions far from overflow

struct Crossing {
  double t;  // on the ray that was cast
  int tri;
  bool enter;  // d.n < 0: the ray enters the solid through this triangle (outward orientation)
};

// A ray against one triangle, in double on the original vertices.
struct Classified {
  bool planar = false;  // zero area, or a plane the ray runs parallel to: no crossing parameter
  double t = 0;         // where the ray meets the triangle's plane
  double dn = 0;        // d . unit normal
  double md = 0;        // signed distance from the ray to the nearest edge line, > 0 inside the triangle
};

// Embree hands the context pointer back to the filter; the record list rides behind it.
struct HitContext {
  RTCIntersectContext rtc;  // first member: the address Embree passes is the address of the whole struct
  std::vector<unsigned>* prims;
};

void record_and_reject(const RTCFilterFunctionNArguments* args) {
  auto* ctx = reinterpret_cast<HitContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    ctx->prims->push_back(RTCHitN_primID(args->hit, args->N, i));
    args->valid[i] = 0;  // rejected: traversal continues to the next crossing
  }
}

void embree_error(void* user, RTCError code, const char* str) {
  auto* msg = static_cast<std::string*>(user);
  if (msg->empty())
    *msg = "Embree error " + std::to_string(static_cast<int>(code)) + (str ? std::string(": ") + str : "");
}

// ---- exact 2-D orientation (the sign of a x b), for the symbolic resolution of degenerate rays ----

// a + b = s + err exactly (Knuth's two-sum; round to nearest, no fast-math).
inline void two_sum(double a, double b, double& s, double& err) {
  s = a + b;
  const double bb = s - a;
  err = (a - (s - bb)) + (b - bb);
}

// The sign of x[0] + ... + x[n-1], exactly: the terms are grown into a non-overlapping expansion (Shewchuk's
// Grow-Expansion), whose sign is that of its largest non-zero component, the last one.
int expansion_sign(const double* x, int n) {
  double e[8];
  int m = 0;
  for (int i = 0; i < n; ++i) {
    double q = x[i];
    for (int j = 0; j < m; ++j) two_sum(q, e[j], q, e[j]);
    e[m++] = q;
  }
  for (int j = m - 1; j >= 0; --j)
    if (e[j] != 0) return e[j] > 0 ? 1 : -1;
  return 0;
}

// sign(ax by - ay bx), exact: a filtered double evaluation (Shewchuk's orient2d bound, which also covers the
// differences that are exact here), else the two products split exactly with fma and summed as an expansion.
// Exact unless a non-zero product falls below ~1e-290 mm^2 (fma's error term would underflow): far below geometry.
int cross_sign(double ax, double ay, double bx, double by) {
  constexpr double kEps = 0x1p-53;
  constexpr double kBound = (3 + 16 * kEps) * kEps;
  const double l = ax * by, r = ay * bx, det = l - r, bound = kBound * (std::abs(l) + std::abs(r));
  if (det > bound) return 1;
  if (-det > bound) return -1;
  const double x[4] = {l, -r, std::fma(ax, by, -l), -std::fma(ay, bx, -r)};
  return expansion_sign(x, 4);
}

inline int sign(double x) { return (x > 0) - (x < 0); }

// Orthonormal e1, e2 with e1 x e2 = d (d unit), from the axis least aligned with d: deterministic.
void basis(const Eigen::Vector3d& d, Eigen::Vector3d& e1, Eigen::Vector3d& e2) {
  const Eigen::Vector3d a =
      std::abs(d.x()) <= std::abs(d.y()) && std::abs(d.x()) <= std::abs(d.z())
          ? Eigen::Vector3d::UnitX()
          : (std::abs(d.y()) <= std::abs(d.z()) ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ());
  e1 = a.cross(d).normalized();
  e2 = d.cross(e1);
}

}  // namespace

struct MeshDexelizer::Impl {
  std::string source;
  std::vector<Eigen::Vector3d> v;            // vertices, double, as given
  std::vector<std::array<int, 3>> tri;       // Embree primID -> vertex indices (triangles with 3 distinct vertices)
  Eigen::Vector3d center, lo, hi;            // bounding box; Embree works relative to its centre
  std::array<std::vector<float>, 3> coords;  // the distinct float vertex coordinates Embree sees, per axis
  std::vector<int> ring_start, ring;         // triangles around each vertex: ring[ring_start[v] .. ring_start[v + 1])
  double tau = 0, margin = 0;                // mm
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string embree_message;

  // A triangle near a degenerate ray, in the plane normal to the ray: vertex k at p[k] = (e1.(v - o), e2.(v - o)),
  // so the ray is the point 0; edge k runs from p[k] to p[k + 1].
  struct Candidate {
    int tri;
    double p[3][2];
    signed char side[3];       // exact sign of p[k] x p[k + 1]: which side of edge k's line the ray is on (0: on it)
    signed char dx[3], dy[3];  // signs of the edge's components: which side a symbolically shifted ray is on
    double t;                  // where the ray crosses it (only for triangles some shifted ray crosses)
  };

  struct Scratch {
    std::vector<unsigned> prims;
    std::vector<Crossing> hits;
    std::vector<std::pair<double, double>> spans;
    std::vector<Candidate> cand;
    std::vector<double> ts;
    std::vector<std::uint32_t> tri_mark, vert_mark;  // == gen: already a candidate / ring already gathered
    std::uint32_t gen = 0;
  };

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  // The line o + t d inside the mesh's bounding box grown by the margin: [ta, tb], false when it misses.
  bool clip(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& ta, double& tb) const {
    ta = -1e300;
    tb = 1e300;
    for (int i = 0; i < 3; ++i) {
      const double l = lo[i] - margin, h = hi[i] + margin;
      if (d[i] == 0) {
        if (o[i] < l || o[i] > h) return false;
        continue;
      }
      double a = (l - o[i]) / d[i], b = (h - o[i]) / d[i];
      if (a > b) std::swap(a, b);
      ta = std::max(ta, a);
      tb = std::min(tb, b);
    }
    return ta <= tb;
  }

  // Casts o + t d over [ta, tb]. Clean: `hits` holds the crossings sorted by t (an even number), each inside its
  // triangle by more than tau. Otherwise the ray is degenerate and false is returned. `lenient` (last resort)
  // keeps crossings strictly inside their triangle in double and drops near-duplicates instead of giving up.
  bool cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double ta, double tb, Scratch& s, bool lenient) const {
    const Eigen::Vector3d org = o + ta * d - center;  // origin moved next to the mesh: float error ~1e-7 E
    const float of[3] = {static_cast<float>(org.x()), static_cast<float>(org.y()), static_cast<float>(org.z())};
    const float df[3] = {static_cast<float>(d.x()), static_cast<float>(d.y()), static_cast<float>(d.z())};
    // Embree replaces a zero direction component by a tiny positive one before its slab tests, so a ray lying
    // exactly in the plane of a BVH box's upper face (a vertex coordinate) leaves that box at t = 0 and never sees
    // its triangles: a ray along the top face of a box stock found nothing. Such rays are cast again with the
    // coordinate one float below, inside those boxes (every combination when two components are zero); the
    // union of what the casts see is classified below as usual.
    int risky[3], nrisky = 0;
    for (int i = 0; i < 3; ++i)
      if (std::abs(df[i]) < 1e-18f && std::binary_search(coords[static_cast<std::size_t>(i)].begin(),
                                                         coords[static_cast<std::size_t>(i)].end(), of[i]))
        risky[nrisky++] = i;
    s.prims.clear();
    for (int mask = 0; mask < (1 << nrisky); ++mask) {
      float oc[3] = {of[0], of[1], of[2]};
      for (int k = 0; k < nrisky; ++k)
        if (mask & (1 << k)) oc[risky[k]] = std::nextafter(oc[risky[k]], -std::numeric_limits<float>::infinity());
      RTCRayHit rh;
      rh.ray.org_x = oc[0];
      rh.ray.org_y = oc[1];
      rh.ray.org_z = oc[2];
      rh.ray.dir_x = df[0];
      rh.ray.dir_y = df[1];
      rh.ray.dir_z = df[2];
      rh.ray.tnear = 0.0f;
      // The margin puts every triangle well inside [0, tb - ta]; the factor covers the float rounding of the span.
      rh.ray.tfar = static_cast<float>((tb - ta) * (1 + 1e-5));
      rh.ray.time = 0.0f;
      rh.ray.mask = 0xFFFFFFFFu;
      rh.ray.id = 0;
      rh.ray.flags = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      HitContext ctx;
      rtcInitIntersectContext(&ctx.rtc);
      ctx.prims = &s.prims;
      rtcIntersect1(scene, &ctx.rtc, &rh);
    }
    std::sort(s.prims.begin(), s.prims.end());
    s.prims.erase(std::unique(s.prims.begin(), s.prims.end()), s.prims.end());

    s.hits.clear();
    bool clean = true;
    for (unsigned p : s.prims) {
      const Classified c = classify(o, d, static_cast<int>(p));
      if (c.planar) {  // zero area, or in-plane: the ray runs along edges or the face itself
        clean = false;
        continue;
      }
      if (lenient ? c.md > 0 : c.md > tau) {
        s.hits.push_back({c.t, static_cast<int>(p), c.dn < 0});
      } else {
        clean = false;
      }
    }
    std::sort(s.hits.begin(), s.hits.end(),
              [](const Crossing& x, const Crossing& y) { return x.t < y.t || (x.t == y.t && x.tri < y.tri); });
    if (lenient) {
      // Two triangles of one edge both claiming the crossing in double: keep one.
      std::size_t w = 0;
      for (std::size_t r = 0; r < s.hits.size(); ++r)
        if (w == 0 || s.hits[r].t - s.hits[w - 1].t > tau) s.hits[w++] = s.hits[r];
      s.hits.resize(w);
      if (s.hits.size() % 2) s.hits.pop_back();
      return true;
    }
    return clean && s.hits.size() % 2 == 0;
  }

  Classified classify(const Eigen::Vector3d& o, const Eigen::Vector3d& d, int p) const {
    Classified r;
    const auto& k = tri[static_cast<std::size_t>(p)];
    const Eigen::Vector3d& a = v[static_cast<std::size_t>(k[0])];
    const Eigen::Vector3d& b = v[static_cast<std::size_t>(k[1])];
    const Eigen::Vector3d& c = v[static_cast<std::size_t>(k[2])];
    const Eigen::Vector3d nraw = (b - a).cross(c - a);
    if (!(nraw.squaredNorm() > 0)) {
      r.planar = true;
      return r;
    }
    // Normalised so that an axis-aligned face has an exact unit normal and t = (a_i - o_i) / d_i bit for bit.
    const Eigen::Vector3d n = nraw.normalized();
    r.dn = d.dot(n);
    if (r.dn == 0) {  // the ray runs in the face's plane direction: Embree saw it only within float error
      r.planar = true;
      return r;
    }
    r.t = (a - o).dot(n) / r.dn;
    // Signed distance of the ray to each edge line, positive inside (Pluecker product over |e x d|).
    const Eigen::Vector3d* vs[3] = {&a, &b, &c};
    r.md = 1e300;
    for (int e = 0; e < 3; ++e) {
      const Eigen::Vector3d& P = *vs[e];
      const Eigen::Vector3d edge = *vs[(e + 1) % 3] - P;
      const double w = (P - o).cross(edge).dot(d);
      const double len = edge.cross(d).norm();
      r.md = std::min(r.md, len > 0 ? (r.dn > 0 ? w : -w) / len : -1e300);
    }
    return r;
  }

  // Resolves a degenerate ray o + t d (e1, e2 span the plane normal to d) by symbolic perturbation, appending the
  // inside spans to s.spans; returns how many of the four perturbed rays came out with an even crossing count.
  //
  // The ray is seen in the plane normal to it, where it is the point 0 and every triangle is its projection (a
  // vertex's projection is one expression of the vertex and the ray, so triangles sharing a vertex or an edge see
  // the same projected coordinates, bit for bit: the projected mesh is as watertight as the mesh). A
  // ray crosses a triangle iff 0 lies inside its projection, decided by the signs of p[k] x p[k + 1] over its three
  // edges, computed exactly. When 0 lies on an edge's line (the ray passes through an edge or a vertex), the ray
  // is shifted symbolically: 0 becomes eps u + eps^2 w for an infinitesimal eps, and the sign of the edge's test
  // becomes the sign of the first non-zero term of  p[k] x p[k + 1]  +  eps (p[k + 1] - p[k]) x u  +  eps^2
  // (p[k + 1] - p[k]) x w  (Simulation of Simplicity). With u, w along the frame's axes the two extra terms are
  // signs of the edge's coordinate differences, exact comparisons, and never both 0 for an edge of a triangle
  // with a non-zero projection. An edge's two triangles evaluate the same quantities with opposite signs, so the
  // shifted ray is strictly on one side of every edge line: it crosses one of the two triangles at an edge the
  // surface passes through, both or neither at a fold, exactly one triangle of a fan around a vertex it passes
  // through, and no triangle whose projection has zero area (faces parallel to the ray). Its crossings are those
  // of a generic ray, so on a closed mesh their count is even and their parity is right, whatever the valence of
  // the vertex or the thinness of the triangles; the crossing parameters are the limits as eps -> 0, the plane
  // intersections of the original ray with the crossed triangles.
  //
  // Four shifts, (u, w) = (e1, e2), (e2, -e1), (-e1, -e2), (-e2, e1): one into each quadrant around the ray. The
  // union of their intervals is the closed set: a ray along a face, an edge or a corner of the solid, or touching
  // it at a point, gets what it touches (as fill_box does on a box's faces and corners).
  //
  // The candidates: what Embree reported for the ray, plus, by flooding, every triangle around a vertex, or across
  // an edge, of a candidate where that vertex or edge lies within tau of the ray (Embree, in float, may report any
  // triangle of a fan at the vertex the ray passes through, or only the neighbour of the triangle the exact test
  // picks at an edge; all of them are needed for the exact test to choose).
  int resolve(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
              Scratch& s) const {
    if (s.tri_mark.size() != tri.size()) s.tri_mark.assign(tri.size(), 0);
    if (s.vert_mark.size() != v.size()) s.vert_mark.assign(v.size(), 0);
    if (++s.gen == 0) {  // wrapped: clear the marks once every 4e9 rays
      std::fill(s.tri_mark.begin(), s.tri_mark.end(), 0);
      std::fill(s.vert_mark.begin(), s.vert_mark.end(), 0);
      s.gen = 1;
    }
    s.cand.clear();
    const auto add = [&](int p) {
      if (s.tri_mark[static_cast<std::size_t>(p)] == s.gen) return;
      s.tri_mark[static_cast<std::size_t>(p)] = s.gen;
      Candidate c;
      c.tri = p;
      const std::array<int, 3>& k3 = tri[static_cast<std::size_t>(p)];
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d r = v[static_cast<std::size_t>(k3[static_cast<std::size_t>(k)])] - o;
        c.p[k][0] = e1.x() * r.x() + e1.y() * r.y() + e1.z() * r.z();
        c.p[k][1] = e2.x() * r.x() + e2.y() * r.y() + e2.z() * r.z();
      }
      s.cand.push_back(c);
    };
    for (unsigned p : s.prims) add(static_cast<int>(p));
    const double tau2 = tau * tau;
    for (std::size_t i = 0; i < s.cand.size(); ++i) {
      // The candidate's vertices and edges within tau of the ray (in double; only the candidate set depends on
      // it) bring in the triangles around those vertices and across those edges.
      const Candidate c = s.cand[i];  // a copy: add() may move s.cand
      const std::array<int, 3> k = tri[static_cast<std::size_t>(c.tri)];
      for (int e = 0; e < 3; ++e) {
        const double* a = c.p[e];
        const double* b = c.p[(e + 1) % 3];
        const int va = k[static_cast<std::size_t>(e)], vb = k[static_cast<std::size_t>((e + 1) % 3)];
        if (a[0] * a[0] + a[1] * a[1] <= tau2 && s.vert_mark[static_cast<std::size_t>(va)] != s.gen) {
          s.vert_mark[static_cast<std::size_t>(va)] = s.gen;
          for (int r = ring_start[static_cast<std::size_t>(va)]; r < ring_start[static_cast<std::size_t>(va) + 1]; ++r)
            add(ring[static_cast<std::size_t>(r)]);
        }
        const double ex = b[0] - a[0], ey = b[1] - a[1], len2 = ex * ex + ey * ey;
        const double f = len2 > 0 ? std::clamp(-(a[0] * ex + a[1] * ey) / len2, 0.0, 1.0) : 0.0;
        const double px = a[0] + f * ex, py = a[1] + f * ey;
        if (px * px + py * py > tau2) continue;
        for (int r = ring_start[static_cast<std::size_t>(va)]; r < ring_start[static_cast<std::size_t>(va) + 1]; ++r) {
          const auto& n = tri[static_cast<std::size_t>(ring[static_cast<std::size_t>(r)])];
          if (n[0] == vb || n[1] == vb || n[2] == vb) add(ring[static_cast<std::size_t>(r)]);
        }
      }
    }

    // Exact side of each edge line, and the crossing parameter of every triangle some shifted ray may cross.
    for (Candidate& c : s.cand) {
      int lo = 0, hi = 0;
      for (int k = 0; k < 3; ++k) {
        const double* a = c.p[k];
        const double* b = c.p[(k + 1) % 3];
        c.side[k] = static_cast<signed char>(cross_sign(a[0], a[1], b[0], b[1]));
        c.dx[k] = static_cast<signed char>(sign(b[0] - a[0]));
        c.dy[k] = static_cast<signed char>(sign(b[1] - a[1]));
        lo = std::min(lo, static_cast<int>(c.side[k]));
        hi = std::max(hi, static_cast<int>(c.side[k]));
      }
      c.t = std::numeric_limits<double>::quiet_NaN();
      if (lo < 0 && hi > 0) continue;  // strictly outside one edge: no shift makes the ray cross it
      c.t = crossing_t(o, d, c);
    }

    int resolved = 0;
    for (int q = 0; q < 4; ++q) {
      s.ts.clear();
      for (const Candidate& c : s.cand) {
        if (std::isnan(c.t)) continue;
        int common = 0;
        bool crossed = true;
        for (int k = 0; k < 3 && crossed; ++k) {
          // The first non-zero term of the edge's test for the shift (u, w) of quadrant q (see above): with
          // g = p[k + 1] - p[k], g x u and g x w are +-g.x or +-g.y.
          int sg = c.side[k];
          if (sg == 0) {
            static constexpr int kU[4][2] = {{0, -1}, {1, 0}, {0, 1}, {-1, 0}};  // g x u = kU[q][0] g.x + kU[q][1] g.y
            static constexpr int kW[4][2] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}};  // g x w likewise
            sg = kU[q][0] * c.dx[k] + kU[q][1] * c.dy[k];
            if (sg == 0) sg = kW[q][0] * c.dx[k] + kW[q][1] * c.dy[k];
          }
          if (sg == 0 || (common != 0 && sg != common)) crossed = false;
          common = sg;
        }
        if (crossed) s.ts.push_back(c.t);
      }
      if (s.ts.size() % 2) continue;  // a crossed triangle missing from the candidates (see the residual risks)
      ++resolved;
      std::sort(s.ts.begin(), s.ts.end());
      // Crossings at one point (a touch) come out in either order within rounding: pairs of the sorted list.
      for (std::size_t k = 0; k + 1 < s.ts.size(); k += 2) s.spans.emplace_back(s.ts[k], s.ts[k + 1]);
    }
    return resolved;
  }

  // Where the ray crosses the candidate's triangle: the plane intersection, as for clean crossings (for faces
  // normal to an axis, fill_box's own arithmetic). The crossing lies in the triangle, so its parameter lies
  // between the vertices' projections onto the ray; a plane intersection further out than tau from that range
  // (a face so nearly parallel to the ray that d.n is rounding) is clamped into it. A face with d.n exactly 0 that
  // the exact test says is crossed gets the barycentric combination of its vertices' parameters.
  double crossing_t(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Candidate& c) const {
    const auto& k = tri[static_cast<std::size_t>(c.tri)];
    double tv[3];
    for (int i = 0; i < 3; ++i) tv[i] = (v[static_cast<std::size_t>(k[static_cast<std::size_t>(i)])] - o).dot(d);
    const double lo = std::min({tv[0], tv[1], tv[2]}), hi = std::max({tv[0], tv[1], tv[2]});
    const Classified cl = classify(o, d, c.tri);
    if (!cl.planar) return cl.t < lo - tau || cl.t > hi + tau ? std::clamp(cl.t, lo, hi) : cl.t;
    double w[3], sum = 0;  // w[i]: the sub-area opposite vertex i, p[i+1] x p[i+2]
    for (int i = 0; i < 3; ++i) {
      const double* a = c.p[(i + 1) % 3];
      const double* b = c.p[(i + 2) % 3];
      w[i] = a[0] * b[1] - a[1] * b[0];
      sum += w[i];
    }
    if (sum == 0) return 0.5 * (lo + hi);
    return std::clamp((w[0] * tv[0] + w[1] * tv[1] + w[2] * tv[2]) / sum, lo, hi);
  }

  // The inside intervals of the ray o + t d, t in [0, length], as floats; e1, e2 span the plane normal to d.
  void ray(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
           double length, Scratch& s, std::vector<Interval>& out, MeshFillStats& stats) const {
    out.clear();
    double ta, tb;
    // A needle with a zero (hence NaN once normalised) or non-finite direction or origin meets nothing.
    if (!d.allFinite() || !o.allFinite() || !clip(o, d, ta, tb)) return;
    ++stats.rays;
    s.spans.clear();
    if (cast(o, d, ta, tb, s, false)) {
      for (std::size_t k = 0; k + 1 < s.hits.size(); k += 2) s.spans.emplace_back(s.hits[k].t, s.hits[k + 1].t);
    } else {
      ++stats.degenerate;
      if (resolve(o, d, e1, e2, s) == 0) {
        ++stats.unresolved;
        cast(o, d, ta, tb, s, true);
        for (std::size_t k = 0; k + 1 < s.hits.size(); k += 2) s.spans.emplace_back(s.hits[k].t, s.hits[k + 1].t);
      }
      std::sort(s.spans.begin(), s.spans.end());
    }
    // Union, clamp to [0, length] as fill_box does (keep what reaches inside the ray), then floats; spans that
    // touch, or meet once rounded to float, become one interval (the store wants them disjoint).
    for (const auto& [t0, t1] : s.spans) {
      if (!(t1 > 0 && t0 < length)) continue;
      const float lo_f = static_cast<float>(std::max(0.0, t0)), hi_f = static_cast<float>(std::min(length, t1));
      if (!out.empty() && lo_f <= out.back().hi) {
        out.back().hi = std::max(out.back().hi, hi_f);
      } else {
        out.push_back({lo_f, hi_f});
      }
    }
  }
};

MeshDexelizer::MeshDexelizer(const core::TriangleMesh& mesh, const std::string& source)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.source = source;
  core::check_closed(mesh, source);  // parity is only meaningful on a closed, consistently oriented surface
  const auto nv = mesh.vertices_mm.rows();
  m.v.resize(static_cast<std::size_t>(nv));
  m.lo = Eigen::Vector3d::Constant(1e300);
  m.hi = Eigen::Vector3d::Constant(-1e300);
  for (Eigen::Index i = 0; i < nv; ++i) {
    m.v[static_cast<std::size_t>(i)] = mesh.vertices_mm.row(i).transpose();
    if (m.v[static_cast<std::size_t>(i)].cwiseAbs().maxCoeff() > kMaxCoordMm)
      throw core::Error(core::located(source, 0, "vertex #" + std::to_string(i + 1) + " lies beyond +-1e9 mm"));
  }
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    const std::array<int, 3> k{mesh.triangles(t, 0), mesh.triangles(t, 1), mesh.triangles(t, 2)};
    if (k[0] == k[1] || k[1] == k[2] || k[0] == k[2]) continue;  // no area; check_closed ignored it too
    m.tri.push_back(k);
    for (int c : k) {
      m.lo = m.lo.cwiseMin(m.v[static_cast<std::size_t>(c)]);
      m.hi = m.hi.cwiseMax(m.v[static_cast<std::size_t>(c)]);
    }
  }
  const double size = (m.hi - m.lo).maxCoeff();
  if (!(size > 0)) throw core::Error(core::located(source, 0, "the mesh has no extent"));
  m.center = 0.5 * (m.lo + m.hi);
  m.tau = kTauRel * size;
  m.margin = kMarginPerTau * m.tau;
  // The triangles around each vertex, for gathering the whole fan at a vertex a degenerate ray passes through.
  m.ring_start.assign(m.v.size() + 1, 0);
  for (const auto& k : m.tri)
    for (int c : k) ++m.ring_start[static_cast<std::size_t>(c) + 1];
  for (std::size_t i = 0; i < m.v.size(); ++i) m.ring_start[i + 1] += m.ring_start[i];
  m.ring.resize(3 * m.tri.size());
  {
    std::vector<int> fill(m.ring_start.begin(), m.ring_start.end() - 1);
    for (std::size_t t = 0; t < m.tri.size(); ++t)
      for (int c : m.tri[t])
        m.ring[static_cast<std::size_t>(fill[static_cast<std::size_t>(c)]++)] = static_cast<int>(t);
  }

  m.device = rtcNewDevice("verbose=0");
  if (!m.device)
    throw core::Error(core::located(
        source, 0,
        "cannot create an Embree device (error " + std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")"));
  rtcSetDeviceErrorFunction(m.device, embree_error, &m.embree_message);
  m.scene = rtcNewScene(m.device);
  // Robust: no optimisations that reduce arithmetic accuracy (the watertight edge tests above rely on it).
  rtcSetSceneFlags(m.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(m.scene, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry g = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.v.size()));
  auto* ib = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.tri.size()));
  if (!vb || !ib) {
    rtcReleaseGeometry(g);
    throw core::Error(core::located(source, 0, "Embree could not allocate the mesh buffers: " + m.embree_message));
  }
  for (std::size_t i = 0; i < m.v.size(); ++i) {
    // Relative to the centre: float keeps ~7 digits of the part's own size, not of its distance from the origin.
    const Eigen::Vector3d r = m.v[i] - m.center;
    vb[3 * i] = static_cast<float>(r.x());
    vb[3 * i + 1] = static_cast<float>(r.y());
    vb[3 * i + 2] = static_cast<float>(r.z());
    for (std::size_t a = 0; a < 3; ++a) m.coords[a].push_back(vb[3 * i + a]);
  }
  for (auto& c : m.coords) {
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
  }
  for (std::size_t t = 0; t < m.tri.size(); ++t)
    for (int c = 0; c < 3; ++c)
      ib[3 * t + static_cast<std::size_t>(c)] = static_cast<unsigned>(m.tri[t][static_cast<std::size_t>(c)]);
  rtcSetGeometryIntersectFilterFunction(g, record_and_reject);
  rtcCommitGeometry(g);
  rtcAttachGeometry(m.scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(m.scene);
  if (rtcGetDeviceError(m.device) != RTC_ERROR_NONE || !m.embree_message.empty())
    throw core::Error(core::located(source, 0, "Embree could not build the mesh's BVH: " + m.embree_message));
}

MeshDexelizer::~MeshDexelizer() = default;

double MeshDexelizer::tolerance_mm() const { return impl_->tau; }

std::vector<Interval> MeshDexelizer::intervals(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                               double length) const {
  Eigen::Vector3d e1, e2;
  const Eigen::Vector3d u = d.normalized();
  basis(u, e1, e2);
  Impl::Scratch s;
  MeshFillStats stats;
  std::vector<Interval> out;
  impl_->ray(o, u, e1, e2, length, s, out, stats);
  return out;
}

MeshFillStats MeshDexelizer::fill(DexelGrid& g) const {
  MeshFillStats total;
  const Impl& m = *impl_;
#pragma omp parallel
  {
    Impl::Scratch s;
    MeshFillStats local;
    std::vector<Interval> out;
    // Each row of the grid is one row of its interval store: rows are written by one thread each.
#pragma omp for schedule(dynamic, 4)
    for (int j = 0; j < g.nv(); ++j) {
      for (int i = 0; i < g.nu(); ++i) {
        m.ray(g.ray_origin(i, j), g.W(), g.U(), g.V(), g.length(), s, out, local);
        g.set_intervals(i, j, out);
      }
    }
#pragma omp critical(vmsim_mesh_stock_stats)
    {
      total.rays += local.rays;
      total.degenerate += local.degenerate;
      total.unresolved += local.unresolved;
    }
  }
  return total;
}

MeshFillStats MeshDexelizer::fill(NeedleSet& n) const {
  MeshFillStats total;
  const Impl& m = *impl_;
  const auto count = static_cast<std::ptrdiff_t>(n.size());
  const auto block = static_cast<std::ptrdiff_t>(NeedleSet::kBlock);
  const std::ptrdiff_t blocks = (count + block - 1) / block;
#pragma omp parallel
  {
    Impl::Scratch s;
    MeshFillStats local;
    std::vector<Interval> out;
#pragma omp for schedule(dynamic, 1)
    for (std::ptrdiff_t b = 0; b < blocks; ++b) {
      for (std::ptrdiff_t k = b * block; k < std::min(count, (b + 1) * block); ++k) {
        const auto kk = static_cast<std::size_t>(k);
        Eigen::Vector3d e1, e2;
        basis(n.direction(kk), e1, e2);
        m.ray(n.origin(kk), n.direction(kk), e1, e2, n.length(kk), s, out, local);
        n.store().set(kk, out);
      }
    }
#pragma omp critical(vmsim_mesh_stock_stats)
    {
      total.rays += local.rays;
      total.degenerate += local.degenerate;
      total.unresolved += local.unresolved;
    }
  }
  return total;
}

void fill_mesh(DexelGrid& grid, const core::TriangleMesh& mesh, const std::string& source) {
  MeshDexelizer(mesh, source).fill(grid);
}

void fill_mesh(NeedleSet& needles, const core::TriangleMesh& mesh, const std::string& source) {
  MeshDexelizer(mesh, source).fill(needles);
}

}  // namespace vmsim::removal
