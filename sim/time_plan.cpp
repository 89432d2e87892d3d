#include "sim/time_plan.hpp"

#include "core/stl.hpp"

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
//   axial ball: parts/plane_cylinder/job_reference.toml (z-map 0.05 mm): 2.08 s over 1.03e8 shadow rays (a short
//     fast job, job_fast.toml, measured 4e-9 per ray: the cost per ray depends on how much the tiles settle);
//   per field ray: the same APT_code runs (whole run CPU less removal and motion: 8.3 to 9.5 s over 1.19e6 rays) and
//     APT_Variable_Axis.txt at z-map 0.1 mm (9.0 s over 2.96e6 rays).
constexpr double kGeneralS = 3.0e-8;      // ball or flat end on the general path
constexpr double kBullNoseS = 7.4e-8;     // bull-nose on the general path
constexpr double kAxialBallS = 2.0e-8;    // ball along the rays
constexpr double kTriDexelRayS = 7.5e-6;  // stock, level set and mesh, writing
constexpr double kZmapRayS = 3.0e-6;      // stock, height grid and its mesh, writing

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
      if (rc == R && (sw.axis - W).norm() <= 1e-12 && across >= 1e-18)
        w.axial_ball_rays += rays;
      else if (rc > 0 && rc < R)
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
      kAxialBallS * work.axial_ball_rays + kGeneralS * work.general_rays + kBullNoseS * work.bull_nose_rays;
  p.run_cpu_s = p.removal_cpu_s + (work.tridexel ? kTriDexelRayS : kZmapRayS) * work.field_rays + motion_cpu_s;
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
          {"field_rays", w.field_rays}};
}

}  // namespace

nlohmann::json plan_time(const core::Job& job, const PlannedMotions& motions, core::Progress& progress) {
  auto not_predicted = [](const std::string& why) {
    return nlohmann::json{{"removal_cpu_s", nullptr}, {"run_cpu_s", nullptr}, {"not_predicted", why}};
  };
  if (job.removal.method == core::RemovalSpec::Method::Vdb) return not_predicted("the vdb method is not modelled");
  if (job.removal.field == core::RemovalSpec::Field::NBuffer) return not_predicted("an N-buffer field is not modelled");
  removal::Box stock;
  if (job.stock.kind == core::StockSpec::Kind::Box) {
    stock = removal::Box{job.stock.min_mm, job.stock.max_mm};
  } else if (job.stock.kind == core::StockSpec::Kind::Mesh) {
    const core::TriangleMesh mesh = core::read_stl(job.stock.mesh_file);
    if (mesh.vertices_mm.rows() == 0) return not_predicted("the stock mesh is empty");
    stock.lo = mesh.vertices_mm.colwise().minCoeff().transpose();
    stock.hi = mesh.vertices_mm.colwise().maxCoeff().transpose();
  } else {
    return not_predicted("a stock that another job leaves is not modelled");
  }
  const bool tridexel = job.removal.field == core::RemovalSpec::Field::TriDexel;
  const MotionWork own{count_removal_work(stock, job.removal.spacing_mm, tridexel, motions.own.sweeps),
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
    ref = MotionWork{count_removal_work(stock, job.removal.spacing_mm, tridexel, motions.reference->sweeps),
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
  out["cost_per_shadow_ray_s"] = {{"axial_ball", kAxialBallS}, {"general", kGeneralS}, {"bull_nose", kBullNoseS}};
  out["cost_per_field_ray_s"] = own.work.tridexel ? kTriDexelRayS : kZmapRayS;
  out["model"] = "sim/time_plan.hpp; costs measured once (sim/time_plan.cpp); bench/README.md compares with runs";
  return out;
}

}  // namespace vmsim::sim
