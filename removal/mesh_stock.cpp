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
// (crossing within tau of an edge line, face parallel to the ray, odd crossing count) and re-cast shifted.
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
//   - A degenerate ray's shifted rays pass delta (1.6e-5 x mesh size) to 2.75 delta away: an interval only they
//     see (the original misses its triangles by more than tau) is dropped, so a feature thinner than delta right
//     at a degenerate ray can be lost or, when the original's own crossings are near, merged with them.
//   - t of a crossing within tau of an edge is the plane intersection of a triangle the ray passes within tau of:
//     off by up to tau / tan(angle between the ray and the face) on grazing faces.
//   - A self-intersecting mesh (check_closed does not look for intersections) gives crossing-parity (XOR) results.
#include "removal/mesh_stock.hpp"

#include "core/error.hpp"
#include "core/stl.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace vmsim::removal {

namespace {

constexpr double kTauRel = 1e-6;     // tau / mesh size: ~10x Embree's float error on a mesh centred at 0
constexpr double kShiftPerTau = 16;  // delta / tau: shifted rays stay clear of the feature that made them degenerate
constexpr int kAttempts = 8;         // angles tried per quadrant before a quadrant is given up
constexpr double kMaxCoordMm = 1e9;  // as core/stl.cpp: keeps float conversions far from overflow

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
  if (msg->empty()) *msg = "Embree error " + std::to_string(static_cast<int>(code)) + (str ? std::string(": ") + str : "");
}

// Orthonormal e1, e2 with e1 x e2 = d (d unit), from the axis least aligned with d: deterministic.
void basis(const Eigen::Vector3d& d, Eigen::Vector3d& e1, Eigen::Vector3d& e2) {
  const Eigen::Vector3d a = std::abs(d.x()) <= std::abs(d.y()) && std::abs(d.x()) <= std::abs(d.z())
                                ? Eigen::Vector3d::UnitX()
                                : (std::abs(d.y()) <= std::abs(d.z()) ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ());
  e1 = a.cross(d).normalized();
  e2 = d.cross(e1);
}

}  // namespace

struct MeshDexelizer::Impl {
  std::string source;
  std::vector<Eigen::Vector3d> v;         // vertices, double, as given
  std::vector<std::array<int, 3>> tri;    // Embree primID -> vertex indices (triangles with 3 distinct vertices)
  Eigen::Vector3d center, lo, hi;         // bounding box; Embree works relative to its centre
  std::array<std::vector<float>, 3> coords;  // the distinct float vertex coordinates Embree sees, per axis
  double tau = 0, delta = 0, margin = 0;  // mm
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string embree_message;

  struct Scratch {
    std::vector<unsigned> prims;
    std::vector<Crossing> hits, own;
    std::vector<std::pair<double, double>> spans;
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

  // A crossing h of a shifted ray, carried back onto the original ray o + t d. If the original ray meets h's
  // triangle, or passes within tau of it, the plane intersection is that point (to ~tau over the crossing angle).
  // If it misses it, the shift moved the crossing across an edge onto a neighbour (on a grazing face this moves
  // t by 1e-3 mm and more), and the original's own clean crossing of the same kind (`own`: entering or leaving)
  // within the shift's reach in t is taken. With neither, the shifted ray sees something the original ray does
  // not (it passed within delta of a corner): NaN, and the caller drops that interval.
  double map_back(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Crossing& h,
                  const std::vector<Crossing>& own) const {
    const Classified c = classify(o, d, h.tri);
    if (!c.planar && c.md >= -tau) return c.t;
    const double reach = 3 * delta / std::max(std::abs(c.dn), 1e-3) + tau;
    const Crossing* best = nullptr;
    for (const Crossing& x : own)
      if (x.enter == h.enter && std::abs(x.t - h.t) <= reach && (!best || std::abs(x.t - h.t) < std::abs(best->t - h.t)))
        best = &x;
    return best ? best->t : std::numeric_limits<double>::quiet_NaN();
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
      s.own.swap(s.hits);  // the original ray's clean crossings, for map_back
      int quadrants = 0;
      for (int q = 0; q < 4; ++q) {
        for (int att = 0; att < kAttempts; ++att) {
          // Angles kept inside the quadrant and off the axes and diagonals, where structured meshes put edges.
          const double th = q * (std::numbers::pi / 2) + 0.37 + 0.137 * att;
          const double sh = delta * (1 + 0.25 * att);
          const Eigen::Vector3d os = o + sh * (std::cos(th) * e1 + std::sin(th) * e2);
          if (!cast(os, d, ta, tb, s, false)) continue;
          // Crossings mapped back onto the original ray through their planes. A pair that comes out reversed is
          // a touch (the original ray meets the solid at one point): kept as that point, as fill_box keeps a
          // box's corner.
          for (std::size_t k = 0; k + 1 < s.hits.size(); k += 2) {
            double t0 = map_back(o, d, s.hits[k], s.own), t1 = map_back(o, d, s.hits[k + 1], s.own);
            if (std::isnan(t0) || std::isnan(t1)) continue;
            if (t0 > t1) t0 = t1 = 0.5 * (t0 + t1);
            s.spans.emplace_back(t0, t1);
          }
          ++quadrants;
          break;
        }
      }
      if (quadrants == 0) {
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

MeshDexelizer::MeshDexelizer(const core::TriangleMesh& mesh, const std::string& source) : impl_(std::make_unique<Impl>()) {
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
  m.delta = kShiftPerTau * m.tau;
  m.margin = 4 * m.delta + m.tau;  // the largest shift is 2.75 delta: shifted rays start outside the box too

  m.device = rtcNewDevice("verbose=0");
  if (!m.device)
    throw core::Error(core::located(source, 0, "cannot create an Embree device (error " +
                                                   std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")"));
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
    for (int c = 0; c < 3; ++c) ib[3 * t + static_cast<std::size_t>(c)] = static_cast<unsigned>(m.tri[t][static_cast<std::size_t>(c)]);
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
double MeshDexelizer::shift_mm() const { return impl_->delta; }

std::vector<Interval> MeshDexelizer::intervals(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double length) const {
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
