#include "sim/time_plan.hpp"

#include "sim/pipeline.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

namespace vmsim::sim {

namespace {

// CPU seconds per shadow ray (see time_plan.hpp), and per field ray for the rest of a run. Measured once, 2026-11-26
// 20:00-20:45 UTC on this project's build host (2 cores shared with other sessions, load average 8-11, Release,
// 2 OpenMP threads), from removal::cut's shadow counts and report.json's removal_cpu (user + sys) on runs that are
// not bench/README.md's validation cases:
//   general, bull-nose: the first 22 GOTOs of APT_code.txt (parts/haas_umc750/chamfer_*.toml), tri-dexel 0.1 mm,
//     750 sweeps over 2.50e8 shadow rays: ball stand-in 7.6 s, bull-nose 18.4 s;
//   per tri-dexel field ray: the same APT_code runs (whole run CPU less removal and motion: 8.3 to 9.5 s over 1.19e6
//     rays).
constexpr double kGeneralS = 3.0e-8;      // ball or flat end on the general path
constexpr double kBullNoseS = 7.4e-8;     // bull-nose on the general path
constexpr double kTriDexelRayS = 7.5e-6;  // stock, level set and mesh, writing
// Measured once, 2026-11-27 00:10-00:17 UTC, same host (load average 13.7-15.2, 2 OpenMP threads), on runs that are
// not validation cases either (bench/README.md, "--plan"):
//   axial ball, per tile of its shadow: the geometric mean of the FreeCAD raster (kern6's bench/removal_growth.py)
//     at 0.1 mm, 4x the program (0.277 s over 1.195e6 tiles: 2.3e-7) and parts/plane_cylinder/job_reference.toml
//     (0.548 s over 9.71e5 tiles, with its reference: 5.6e-7). The two differ 2.4x (the rays a tile's bound leaves
//     open cost more where the cut is deep); one cost per tile keeps both within 2x of it.
//   per z-map field ray: the same raster at 0.1 mm, 4x (1.0e6 rays), whole run less removal and motion, with its
//     outputs off (stock, height grid, .npy: 0.245 s), and then with one output on at a time.
constexpr double kAxialBallTileS = 3.6e-7;  // ball along the rays, per tile of its shadow
constexpr double kZmapRayS = 2.4e-7;        // stock, height grid, .npy
constexpr double kZmapMeshRayS = 1.0e-6;    // part.stl and part.vtp (full mesh)
constexpr double kZmapCsvRayS = 0.8e-7;     // the CSV grids
constexpr double kZmapX3pRayS = 0.2e-7;     // the X3P files

double field_ray_s(const RemovalWork& w) {
  if (w.tridexel) return kTriDexelRayS;
  return kZmapRayS + (w.part_mesh ? kZmapMeshRayS : 0) + (w.csv ? kZmapCsvRayS : 0) + (w.x3p ? kZmapX3pRayS : 0);
}

// The kernel's tiles over one grid (removal/cut.cpp: kBlock = 8 rows, 2^shift columns, shift from the smallest tool
// radius) with an upper bound of each tile's highest material top, starting at the stock's top (the grid's length).
struct TileTops {
  int cols = 32, nu = 0, nv = 0, ntu = 0, ntv = 0;
  std::vector<double> top;
};

// Ball-end sweep with its axis along the rays: the centre's (u, v) segment a + s e, s in [0, 1], and its height w0 +
// s dw along the rays, radius R. Its lower surface over a tile (centre q, half-diagonal hd) is at least the lowest
// centre height within R + hd of q less R ... sharpened by the tile's least distance from the segment; where the tile
// lies within R of one centre, at most that centre's height less its bottom's drop at the tile's farthest point.
void follow_tiles(TileTops& t, const removal::SweptTool& sw, const Eigen::Vector3d& origin, const Eigen::Vector3d& lo_s,
                  const Eigen::Vector3d& hi_s, int au, int av, int aw, double h, RemovalWork& w) {
  const double R = sw.tool.radius_mm;
  const Eigen::Vector3d c0 = sw.tip0 + R * sw.axis - origin;  // in the grid's frame, as lo_s and hi_s
  const Eigen::Vector2d a(c0[au], c0[av]), e(sw.d[au], sw.d[av]);
  const double w0 = c0[aw], dw = sw.d[aw], ee = e.squaredNorm();
  const int i0 = std::max(0, int(std::ceil(lo_s[au] / h))), i1 = std::min(t.nu - 1, int(std::floor(hi_s[au] / h)));
  const int j0 = std::max(0, int(std::ceil(lo_s[av] / h))), j1 = std::min(t.nv - 1, int(std::floor(hi_s[av] / h)));
  if (i1 < i0 || j1 < j0) return;
  for (int tj = j0 / 8; tj <= j1 / 8; ++tj) {
    const int r0 = std::max(j0, tj * 8), r1 = std::min(j1, tj * 8 + 7);
    for (int ti = i0 / t.cols; ti <= i1 / t.cols; ++ti) {
      const int q0 = std::max(i0, ti * t.cols), q1 = std::min(i1, ti * t.cols + t.cols - 1);
      w.axial_ball_tiles += 1;
      const Eigen::Vector2d q(0.5 * (q0 + q1) * h, 0.5 * (r0 + r1) * h);
      const double hd = 0.5 * h * std::hypot(q1 - q0, r1 - r0);
      // Closest centre to q, and the centres within R + hd of it (a chord of the segment).
      const double sc = ee > 0 ? std::clamp((q - a).dot(e) / ee, 0.0, 1.0) : 0.0;
      const double dc = (a + sc * e - q).norm();
      if (dc >= R + hd) continue;
      double sa = sc, sb = sc;
      if (ee > 0) {
        const double half = std::sqrt(std::max(0.0, (R + hd) * (R + hd) - dc * dc) / ee);
        sa = std::max(0.0, sc - half), sb = std::min(1.0, sc + half);
      }
      const double dmin = std::max(0.0, dc - hd);
      const double lb = std::min(w0 + sa * dw, w0 + sb * dw) - std::sqrt(std::max(0.0, R * R - dmin * dmin));
      double& top = t.top[std::size_t(tj) * std::size_t(t.ntu) + std::size_t(ti)];
      if (lb >= top) continue;  // settled by the tile's bound
      w.axial_ball_open_rays += double(q1 - q0 + 1) * double(r1 - r0 + 1);
      const double dmax = dc + hd;
      if (dmax < R) top = std::min(top, w0 + sc * dw - std::sqrt(R * R - dmax * dmax));
    }
  }
}

// Lattice indices [i0, i1] within [0, n) whose coordinate i h lies in [lo, hi] (removal::footprint's rounding).
double lattice_count(double lo, double hi, double h, int n) {
  const double i0 = std::max(0.0, std::ceil(lo / h)), i1 = std::min(double(n - 1), std::floor(hi / h));
  return i1 >= i0 ? i1 - i0 + 1 : 0.0;
}

}  // namespace

RemovalWork count_removal_work(const removal::Box& stock, double spacing_mm, bool tridexel,
                               const std::vector<removal::SweptTool>& sweeps) {
  RemovalWork w;
  w.tridexel = tridexel;
  w.sweeps = double(sweeps.size());
  const std::vector<removal::GridShape> shapes = removal::field_shape(stock, spacing_mm, tridexel);
  // The grids' ray directions W and their (U, V) axes, as coordinate indices (removal/fields.cpp's make_*).
  struct Axes {
    int u, v, w;
  };
  const std::vector<Axes> axes =
      tridexel ? std::vector<Axes>{{1, 2, 0}, {2, 0, 1}, {0, 1, 2}} : std::vector<Axes>{{0, 1, 2}};
  for (const removal::GridShape& s : shapes) w.field_rays += double(s.nu) * double(s.nv);
  // removal/cut.cpp's tile width: about a fraction of the smallest tool radius.
  double r_min = 1e300;
  for (const removal::SweptTool& sw : sweeps) r_min = std::min(r_min, sw.tool.radius_mm);
  const int tile_cols =
      1 << (sweeps.empty() ? 5 : std::clamp(static_cast<int>(std::lround(std::log2(r_min / (2 * spacing_mm)))), 2, 5));
  std::vector<TileTops> tiles(shapes.size());
  const Eigen::Vector3d extent = stock.hi - stock.lo;
  for (const removal::SweptTool& sw : sweeps) {
    Eigen::Vector3d lo, hi;
    sw.bounds(lo, hi);
    lo -= stock.lo, hi -= stock.lo;
    for (std::size_t g = 0; g < axes.size(); ++g) {
      const Axes& a = axes[g];
      const double rays = lattice_count(lo[a.u], hi[a.u], spacing_mm, shapes[g].nu) *
                          lattice_count(lo[a.v], hi[a.v], spacing_mm, shapes[g].nv);
      if (rays == 0) continue;
      const Eigen::Vector3d W = Eigen::Vector3d::Unit(a.w);
      const double rc = sw.tool.corner_radius_mm, R = sw.tool.radius_mm;
      // removal/cut_internal.hpp's axial_ball: a ball end along the rays that moves across them.
      const double across = (sw.d - sw.d.dot(W) * W).squaredNorm();
      if (rc == R && (sw.axis - W).norm() <= 1e-12 && across >= 1e-18) {
        w.axial_ball_rays += rays;
        TileTops& t = tiles[g];
        if (t.top.empty()) {
          t.cols = tile_cols, t.nu = shapes[g].nu, t.nv = shapes[g].nv;
          t.ntu = (t.nu + tile_cols - 1) / tile_cols, t.ntv = (t.nv + 7) / 8;
          t.top.assign(std::size_t(t.ntu) * std::size_t(t.ntv), extent[a.w]);
        }
        follow_tiles(t, sw, stock.lo, lo, hi, a.u, a.v, a.w, spacing_mm, w);
      } else if (rc > 0 && rc < R)
        w.bull_nose_rays += rays;
      else
        w.general_rays += rays;
    }
  }
  return w;
}

TimePrediction predict_time(const RemovalWork& work, double motion_cpu_s) {
  TimePrediction p;
  p.removal_cpu_s =
      kAxialBallTileS * work.axial_ball_tiles + kGeneralS * work.general_rays + kBullNoseS * work.bull_nose_rays;
  p.run_cpu_s = p.removal_cpu_s + field_ray_s(work) * work.field_rays + motion_cpu_s;
  return p;
}

namespace {

// One motion's share: its sweeps' shadow counts and the CPU computing it took.
struct MotionWork {
  RemovalWork work;
  double motion_cpu_s = 0;
};

nlohmann::json counts_json(const RemovalWork& w) {
  return {{"sweeps", w.sweeps},
          {"shadow_rays",
           {{"axial_ball", w.axial_ball_rays}, {"general", w.general_rays}, {"bull_nose", w.bull_nose_rays}}},
          {"axial_ball_tiles", w.axial_ball_tiles},
          {"axial_ball_open_rays", w.axial_ball_open_rays},
          {"field_rays", w.field_rays}};
}

}  // namespace

nlohmann::json plan_time(const core::Job& job, const PlannedMotions& motions, core::Progress& progress) {
  auto not_predicted = [](const std::string& why) {
    return nlohmann::json{{"removal_cpu_s", nullptr}, {"run_cpu_s", nullptr}, {"not_predicted", why}};
  };
  if (job.removal.method == core::RemovalSpec::Method::Vdb) return not_predicted("the vdb method is not modelled");
  if (job.removal.field == core::RemovalSpec::Field::NBuffer) return not_predicted("an N-buffer field is not modelled");
  const std::optional<removal::Box> box = stock_box(job);
  if (!box)
    return not_predicted(job.stock.kind == core::StockSpec::Kind::Mesh ? "the stock mesh is empty"
                                                                       : "a stock that another job leaves is not modelled");
  const removal::Box stock = *box;
  const bool tridexel = job.removal.field == core::RemovalSpec::Field::TriDexel;
  // The z-map's outputs as sim/run_outputs.cpp decides them (a large grid leaves the mesh and CSV out by default).
  auto with_outputs = [&](RemovalWork w) {
    using O = core::OutputsSpec;
    const O& o = job.outputs;
    const bool large = w.field_rays > o.large_grid_nodes;
    w.part_mesh = o.part_mesh == O::Mesh::Auto ? !large : o.part_mesh != O::Mesh::None;
    w.csv = o.csv == O::Csv::Always || (o.csv == O::Csv::Auto && !large);
    w.x3p = o.x3p;
    return w;
  };
  const MotionWork own{with_outputs(count_removal_work(stock, job.removal.spacing_mm, tridexel, motions.own.sweeps)),
                       motions.own.cpu_s};
  // The reference a run computes beside (sim/run.cpp): the same program at other feeds or along its programmed path,
  // cut into a field of the same shape; a stock reference is a copy; a reference job is a run of its own.
  std::optional<MotionWork> ref;
  double ref_run_cpu = 0;
  if (job.reference.kind == core::ReferenceSpec::Kind::Job) {
    const core::Job rj = core::load_job(job.reference.job_file);
    const nlohmann::json r = plan_time(rj, plan_motions(rj, 1.0, progress, motions.reference), progress);
    if (r["run_cpu_s"].is_null()) return not_predicted("the reference job: " + r["not_predicted"].get<std::string>());
    ref_run_cpu = r["run_cpu_s"].get<double>();
  } else if (motions.reference) {
    ref =
        MotionWork{with_outputs(count_removal_work(stock, job.removal.spacing_mm, tridexel, motions.reference->sweeps)),
                   motions.reference->cpu_s};
  }
  const TimePrediction p = predict_time(own.work, own.motion_cpu_s);
  double run = p.run_cpu_s + ref_run_cpu;
  nlohmann::json out{{"removal_cpu_s", p.removal_cpu_s}, {"motion_cpu_s", own.motion_cpu_s}};
  out.update(counts_json(own.work));
  if (ref) {
    // Its field's surfaces are made and written too: the same cost per ray.
    const TimePrediction rp = predict_time(ref->work, ref->motion_cpu_s);
    run += rp.run_cpu_s;
    out["reference"] = counts_json(ref->work);
    out["reference"]["removal_cpu_s"] = rp.removal_cpu_s;
    out["reference"]["motion_cpu_s"] = ref->motion_cpu_s;
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Job) {
    out["reference"] = {{"run_cpu_s", ref_run_cpu}};
  }
  out["run_cpu_s"] = run;
  out["cost_per_shadow_ray_s"] = {{"general", kGeneralS}, {"bull_nose", kBullNoseS}};
  out["cost_per_axial_ball_tile_s"] = kAxialBallTileS;
  out["cost_per_field_ray_s"] = field_ray_s(own.work);
  out["model"] = "sim/time_plan.hpp; costs measured once (sim/time_plan.cpp); bench/README.md compares with runs";
  return out;
}

}  // namespace vmsim::sim
