#include "removal/fields.hpp"

#include "core/error.hpp"
#include "removal/cut_internal.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace vmsim::removal {

namespace {
int count(double extent, double h) { return std::max(1, static_cast<int>(std::floor(extent / h + 1e-9)) + 1); }

// Parameter range of the ray o + t u inside the box (slab method); false when it misses.
bool ray_box(const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Box& b, double& t0, double& t1) {
  t0 = -1e300;
  t1 = 1e300;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(u[i]) < 1e-15) {
      if (o[i] < b.lo[i] || o[i] > b.hi[i]) return false;
      continue;
    }
    double a = (b.lo[i] - o[i]) / u[i], c = (b.hi[i] - o[i]) / u[i];
    if (a > c) std::swap(a, c);
    t0 = std::max(t0, a);
    t1 = std::min(t1, c);
  }
  return t0 <= t1;
}
}  // namespace

std::pair<int, int> tile_rows(int rows, const Tile& t) {
  if (t.count < 1 || t.index < 0 || t.index >= t.count) throw core::Error("tile: expected 0 <= index < count");
  const auto first = static_cast<int>(static_cast<long long>(rows) * t.index / t.count);
  const auto end = static_cast<int>(static_cast<long long>(rows) * (t.index + 1) / t.count);
  if (end <= first)
    throw core::Error("tiles: " + std::to_string(t.count) + " tiles for a grid of " + std::to_string(rows) +
                      " rows leave a tile empty; use at most " + std::to_string(rows) + " processes");
  return {first, end};
}

namespace {
// The rows of a grid of nu x nv rays that a tile holds, as a window of the lattice.
DexelGrid tile_grid(const Eigen::Vector3d& o, const Eigen::Vector3d& U, const Eigen::Vector3d& V, double h, int nu,
                    int nv, double length, const Tile& tile) {
  const auto [first, end] = tile_rows(nv, tile);
  return DexelGrid(o, U, V, h, h, nu, end - first, length, first);
}
}  // namespace

DexelGrid make_zmap(const Box& r, double h, const Tile& tile) {
  if (!(h > 0)) throw core::Error("z-map: the spacing must be > 0");
  const Eigen::Vector3d ext = r.hi - r.lo;
  return tile_grid(r.lo, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), h, count(ext.x(), h), count(ext.y(), h),
                   ext.z(), tile);
}

TriDexel make_tridexel(const Box& r, double h, const Tile& tile) {
  if (!(h > 0)) throw core::Error("tri-dexel: the spacing must be > 0");
  const Eigen::Vector3d e = r.hi - r.lo;
  TriDexel t;
  t.x = tile_grid(r.lo, Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(), h, count(e.y(), h), count(e.z(), h), e.x(),
                  tile);
  t.y = tile_grid(r.lo, Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX(), h, count(e.z(), h), count(e.x(), h), e.y(),
                  tile);
  t.z = tile_grid(r.lo, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), h, count(e.x(), h), count(e.y(), h), e.z(),
                  tile);
  return t;
}

std::vector<GridShape> field_shape(const Box& r, double h, bool tridexel) {
  if (!(h > 0)) throw core::Error("field: the spacing must be > 0");
  const Eigen::Vector3d e = r.hi - r.lo;
  if (!tridexel) return {{count(e.x(), h), count(e.y(), h)}};
  return {{count(e.y(), h), count(e.z(), h)}, {count(e.z(), h), count(e.x(), h)}, {count(e.x(), h), count(e.y(), h)}};
}

void fill_box(DexelGrid& g, const Box& stock) {
  // Written in place (IntervalStore::head): set_intervals builds a std::vector per ray, a heap allocation for every
  // node that cost more than the ray-box test (the removal bench's profile). Same intervals, same floats.
  const std::vector<Interval> none;
#pragma omp parallel for schedule(static)
  for (int j = 0; j < g.nv(); ++j) {
    Interval* row = g.head_row(j);
    for (int i = 0; i < g.nu(); ++i) {
      double t0, t1;
      const bool hit = ray_box(g.ray_origin(i, j), g.W(), stock, t0, t1) && t1 > 0 && t0 < g.length();
      const Interval iv =
          hit ? Interval{static_cast<float>(std::max(0.0, t0)), static_cast<float>(std::min(g.length(), t1))}
              : Interval{1.0f, -1.0f};  // IntervalStore's empty ray
      if (std::isnan(row[i].lo))        // the ray's intervals are in the overflow table: set() clears them
        g.set_intervals(i, j, hit ? std::vector<Interval>{iv} : none);
      else
        row[i] = iv;
    }
  }
}

void fill_box(NeedleSet& n, const Box& stock) {
  const auto count_n = static_cast<std::ptrdiff_t>(n.size());
  const auto blocks =
      (count_n + static_cast<std::ptrdiff_t>(NeedleSet::kBlock) - 1) / static_cast<std::ptrdiff_t>(NeedleSet::kBlock);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t b = 0; b < blocks; ++b) {
    for (std::ptrdiff_t k = b * NeedleSet::kBlock;
         k < std::min(count_n, (b + 1) * static_cast<std::ptrdiff_t>(NeedleSet::kBlock)); ++k) {
      const auto kk = static_cast<std::size_t>(k);
      double t0, t1;
      if (ray_box(n.origin(kk), n.direction(kk), stock, t0, t1) && t1 > 0 && t0 < n.length(kk)) {
        n.store().set(
            kk, {Interval{static_cast<float>(std::max(0.0, t0)), static_cast<float>(std::min(n.length(kk), t1))}});
      } else {
        n.store().set(kk, {});
      }
    }
  }
}

CutStats cut(NeedleSet& n, const std::vector<SweptTool>& sweeps) {
  // Each block of needles gathers the sweeps whose bounding boxes meet its own (a sort-and-sweep on x keeps this
  // near-linear for spatially ordered needles, as a measurement grid's are).
  const std::size_t nblocks = (n.size() + NeedleSet::kBlock - 1) / NeedleSet::kBlock;
  std::vector<Box> sb(sweeps.size());
  std::vector<std::size_t> order(sweeps.size());
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    sweeps[k].bounds(sb[k].lo, sb[k].hi);
    order[k] = k;
  }
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return sb[a].lo.x() < sb[b].lo.x(); });
  double max_width = 0;
  for (const Box& b : sb) max_width = std::max(max_width, b.hi.x() - b.lo.x());
  std::vector<Box> sbw(sb.size());  // widened as removal/cut_internal.hpp widens a sweep's extent along the rays
  for (std::size_t k = 0; k < sb.size(); ++k) {
    const Eigen::Array3d m = 1e-6 * (1 + sb[k].lo.array().abs().max(sb[k].hi.array().abs()));
    sbw[k] = Box{sb[k].lo - m.matrix(), sb[k].hi + m.matrix()};
  }
  std::size_t tests = 0, cuts = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : tests, cuts)
  for (std::ptrdiff_t bi = 0; bi < static_cast<std::ptrdiff_t>(nblocks); ++bi) {
    const std::size_t k0 = static_cast<std::size_t>(bi) * NeedleSet::kBlock,
                      k1 = std::min(n.size(), k0 + NeedleSet::kBlock);
    Box bb{Eigen::Vector3d::Constant(1e300), Eigen::Vector3d::Constant(-1e300)};
    for (std::size_t k = k0; k < k1; ++k) {
      const Eigen::Vector3d a = n.origin(k), e = a + n.length(k) * n.direction(k);
      bb.lo = bb.lo.cwiseMin(a.cwiseMin(e));
      bb.hi = bb.hi.cwiseMax(a.cwiseMax(e));
    }
    // Sweeps with lo.x in [bb.lo.x - max_width, bb.hi.x].
    auto first = std::lower_bound(order.begin(), order.end(), bb.lo.x() - max_width,
                                  [&](std::size_t s, double v) { return sb[s].lo.x() < v; });
    std::vector<std::size_t> cand;
    for (auto it = first; it != order.end() && sb[*it].lo.x() <= bb.hi.x(); ++it) {
      const Box& s = sb[*it];
      if ((s.hi.array() >= bb.lo.array()).all() && (s.lo.array() <= bb.hi.array()).all()) cand.push_back(*it);
    }
    std::sort(cand.begin(), cand.end());  // program order (the result does not depend on it, but keep it tidy)
    for (std::size_t k = k0; k < k1; ++k) {
      // The box of the needle's material (the segment from its lowest to its highest point): a sweep whose box,
      // widened well beyond round-off, misses it leaves the needle as it is (its cut lies in its box), so it needs no
      // exact test. Needles are short next to the passes that reach their block, and most of those pass beside them.
      Box mat;
      auto material = [&] {
        const double lo = n.store().bottom(k), hi = n.store().top(k);
        if (std::isnan(lo)) return false;
        const Eigen::Vector3d a = n.origin(k) + lo * n.direction(k), e = n.origin(k) + hi * n.direction(k);
        mat = Box{a.cwiseMin(e), a.cwiseMax(e)};
        return true;
      };
      if (!material()) continue;  // an empty needle stays empty
      for (std::size_t s : cand) {
        if ((sbw[s].hi.array() < mat.lo.array()).any() || (sbw[s].lo.array() > mat.hi.array()).any()) continue;
        double t0, t1;
        ++tests;
        if (!(detail::reference_bull_solver() ? ray_interval_reference : ray_interval)(sweeps[s], n.origin(k),
                                                                                       n.direction(k), t0, t1))
          continue;
        if (t1 <= 0 || t0 >= n.length(k) || t1 - t0 <= 1e-9) continue;  // zero-width contacts cut nothing
        n.store().subtract(k, t0, t1);
        ++cuts;
        if (!material()) break;
      }
    }
  }
  CutStats st;
  st.ray_tests = tests;
  st.cuts = cuts;
  return st;
}

core::HeightGrid height_grid(const DexelGrid& g) {
  if ((g.W() - Eigen::Vector3d::UnitZ()).norm() > 1e-12)
    throw core::Error("height grid: the dexel grid is not along +Z");
  core::HeightGrid h;
  h.x0_mm = g.origin().x();
  h.y0_mm = g.v_first() == 0 ? g.origin().y() : g.origin().y() + g.v_of(0);  // a window: its first row
  h.dx_mm = g.du();
  h.dy_mm = g.dv();
  h.z_mm.resize(g.nv(), g.nu());
  for (int j = 0; j < g.nv(); ++j)
    for (int i = 0; i < g.nu(); ++i) h.z_mm(j, i) = g.origin().z() + g.top(i, j);
  return h;
}

}  // namespace vmsim::removal
