// vmsim run JOB: the whole chain. Program -> interpolator -> drives -> kinematics -> material removal -> surfaces,
// and the marks: the signed deviation of the predicted surface from the reference surface.
#include "app/axis_following.hpp"
#include "app/axis_models.hpp"
#include "app/commands.hpp"
#include "app/contour_stats.hpp"
#include "app/job_program.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "app/result_images.hpp"
#include "app/signals.hpp"
#include "app/tool_poses.hpp"
#include "core/atomic_file.hpp"
#include "core/contour.hpp"
#include "core/error.hpp"
#include "core/interp.hpp"
#include "core/job.hpp"
#include "core/kinematics.hpp"
#include "core/program.hpp"
#include "core/stl.hpp"
#include "core/units.hpp"
#include "drives/oga_schedule.hpp"
#include "drives/simulate.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/marks.hpp"
#include "metrology/x3p.hpp"
#include "removal/fields.hpp"
#include "removal/mesh_stock.hpp"
#include "removal/surface.hpp"
#include "removal/track.hpp"
#include "removal/vdb_part.hpp"
#include "render/mesh_io.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>

namespace vmsim::app {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

const char* motion_name(core::RemovalSpec::Motion m) {
  switch (m) {
    case core::RemovalSpec::Motion::Actual: return "actual";
    case core::RemovalSpec::Motion::Setpoints: return "setpoints";
    case core::RemovalSpec::Motion::Program: return "program";
  }
  return "?";
}

// One job's motion through the chain, as far as its removal needs it.
struct Motion {
  core::ToolPath program;  // tool tip, workpiece frame
  core::InterpResult interp;
  std::optional<drives::AxisResponse> response;
  std::optional<core::ContourError> contour;
  nlohmann::json timings = nlohmann::json::object();
};

Motion simulate_motion(const core::Job& job, double feed_scale, core::RemovalSpec::Motion kind, Progress& progress) {
  Motion m;
  auto t0 = Clock::now();
  m.program = read_job_program(job);
  m.timings["read_program"] = seconds_since(t0);
  if (kind == core::RemovalSpec::Motion::Program) return m;
  t0 = Clock::now();
  progress.stage(job.name + ": interpolation");
  core::InterpOptions iopt;
  iopt.period_s = job.interp.period_s;
  iopt.tolerance_mm = job.interp.tolerance_mm;
  iopt.feed_scale = feed_scale;
  m.interp = core::interpolate(core::toolpath_in_axis_space(m.program, job.machine), job.machine, iopt);
  progress.done();
  m.timings["interpolate"] = seconds_since(t0);
  if (kind == core::RemovalSpec::Motion::Actual) {
    t0 = Clock::now();
    progress.stage(job.name + ": servo drives");
    // [job] gain_schedule (vmsim oga) holds gains for the job's own feeds; a feed-scaled reference (kind = "feed")
    // runs the drives' own gains.
    drives::SimulateOptions sopt;
    drives::GainSchedule schedule;
    if (job.gain_schedule_file && feed_scale == 1.0) {
      schedule = drives::read_gain_schedule(*job.gain_schedule_file, m.interp.setpoints, job.machine);
      sopt.gains = &schedule;
    }
    // [job] axis_models (vmsim identify): those axes run as their identified transfer functions, at any feed.
    const JobAxisModels models = job_axis_models(job, std::nullopt);
    if (models.any()) sopt.axis_models = &models.per_axis;
    m.response = drives::simulate_axes(m.interp.setpoints, job.machine, sopt);
    progress.done();
    m.timings["drives"] = seconds_since(t0);
  }
  return m;
}

double tlo_at(const Motion& m, Eigen::Index k) {
  const core::Setpoints& sp = m.interp.setpoints;
  const int mi = sp.move_index[std::min(k, sp.samples() - 1)];
  return mi >= 0 ? m.program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
}

// The track tolerance a job cuts at: its own, or when it gives none and a level set cuts a turning tool, voxel / 10
// (core/job.hpp: the orientation sub-steps are exact sweeps the level set pays for one by one, and it shows no finer
// detail than about a tenth of its voxel; 3-axis tracks keep the default, which costs no extra sweeps there).
double track_tolerance(const core::Job& job, bool tool_turns) {
  if (job.removal.track_tolerance_given || job.removal.method != core::RemovalSpec::Method::Vdb || !tool_turns)
    return job.removal.track_tolerance_mm;
  return job.removal.voxel_mm / 10;
}

bool track_turns(const removal::PoseTrack& tr) {
  const Eigen::MatrixXd& a = tr.axis_per_sample;
  for (Eigen::Index k = 1; k < a.rows(); ++k)
    if ((a.row(k).normalized() - a.row(0).normalized()).norm() > 1e-12) return true;
  return false;
}

// Tool-tip track of the motion that cuts.
removal::PoseTrack track_of(const Motion& m, const core::Job& job, core::RemovalSpec::Motion kind) {
  removal::PoseTrack tr;
  if (kind == core::RemovalSpec::Motion::Program && job.machine.kinematics == "chain" && program_turns_tool(m.program)) {
    // A five-axis program: tool tip and axis along the programmed moves (app/tool_poses.hpp), sampled within a tenth
    // of the track tolerance as the arcs below are.
    const auto kin = core::make_kinematics(job.machine);
    return program_pose_track(m.program, core::toolpath_in_axis_space(m.program, job.machine), *kin, job.machine,
                              removal::make_tool(job.tool), 0.1 * track_tolerance(job, true));
  }
  if (kind == core::RemovalSpec::Motion::Program) {
    // The programmed geometry itself: line ends, and arcs sampled finely enough that their chords stay within a
    // tenth of the track tolerance (the kernel's sweeps are exact between points).
    std::vector<Eigen::Vector3d> pts;
    if (!m.program.moves.empty()) pts.push_back(m.program.moves.front().start.head<3>());
    for (const core::Move& mv : m.program.moves) {
      if (mv.kind == core::MotionKind::Line) {
        pts.push_back(mv.end.head<3>());
        continue;
      }
      int i1 = 0, i2 = 1, iw = 2;
      if (mv.plane == core::ArcPlane::ZX) i1 = 2, i2 = 0, iw = 1;
      if (mv.plane == core::ArcPlane::YZ) i1 = 1, i2 = 2, iw = 0;
      const double c1 = mv.centre_mm[0], c2 = mv.centre_mm[1];
      const double r0 = std::hypot(mv.start[i1] - c1, mv.start[i2] - c2), r1 = std::hypot(mv.end[i1] - c1, mv.end[i2] - c2);
      const double t0 = std::atan2(mv.start[i2] - c2, mv.start[i1] - c1), te = std::atan2(mv.end[i2] - c2, mv.end[i1] - c1);
      const int turns = std::abs(mv.rotation) - 1;
      double sweep;
      const bool full = std::hypot(mv.end[i1] - mv.start[i1], mv.end[i2] - mv.start[i2]) < 1e-9;
      if (mv.rotation > 0) {
        sweep = std::fmod(te - t0 + 4 * core::units::kPi, 2 * core::units::kPi);
        if (full) sweep = 2 * core::units::kPi;
        sweep += 2 * core::units::kPi * turns;
      } else {
        sweep = std::fmod(t0 - te + 4 * core::units::kPi, 2 * core::units::kPi);
        if (full) sweep = 2 * core::units::kPi;
        sweep = -(sweep + 2 * core::units::kPi * turns);
      }
      const double tol = 0.1 * job.removal.track_tolerance_mm, r = std::max(r0, r1);
      const double dphi = 2 * std::acos(std::max(0.0, 1 - tol / std::max(r, 1e-9)));
      const int n = std::max(1, static_cast<int>(std::ceil(std::abs(sweep) / std::max(dphi, 1e-6))));
      for (int k = 1; k <= n; ++k) {
        const double f = double(k) / n, th = t0 + f * sweep, rr = r0 + f * (r1 - r0);
        Eigen::Vector3d p = (mv.start.head<3>() + f * (mv.end.head<3>() - mv.start.head<3>())).eval();
        p[i1] = c1 + rr * std::cos(th);
        p[i2] = c2 + rr * std::sin(th);
        p[iw] = mv.start[iw] + f * (mv.end[iw] - mv.start[iw]);
        pts.push_back(k == n ? Eigen::Vector3d(mv.end.head<3>()) : p);
      }
    }
    tr.tip_mm.resize(static_cast<Eigen::Index>(pts.size()), 3);
    for (std::size_t k = 0; k < pts.size(); ++k) tr.tip_mm.row(static_cast<Eigen::Index>(k)) = pts[k].transpose();
    return tr;
  }
  const auto kin = core::make_kinematics(job.machine);
  const core::Setpoints& sp = m.interp.setpoints;
  const bool actual = kind == core::RemovalSpec::Motion::Actual;
  const Eigen::MatrixXd& axes = actual ? m.response->position : sp.position;
  // Tool tip and axis per sample through the forward transform (a turning axis on five-axis machines). Between Te
  // samples of the actual motion the tip follows the cubic through both samples with the drives' velocities through
  // the chain's Jacobian (Cartesian machine: the X Y Z velocities).
  return pose_track_from_axes(*kin, job.machine, axes, actual ? &m.response->velocity : nullptr, sp.period_s,
                              [&](Eigen::Index k) { return tlo_at(m, k); });
}

// The stock's dexels, or its level set (method "vdb": `kind` then only says which surfaces are read back).
struct Field {
  core::RemovalSpec::Field kind = core::RemovalSpec::Field::ZMap;
  bool vdb = false;
  removal::VdbPart part;               // vdb
  double vdb_estimate_bytes = 0;       // vdb: the level set's memory stated before the run
  double vdb_mesh_estimate_bytes = 0;  // vdb: the part mesh's
  removal::Box region;
  double spacing_mm = 0.05;
  removal::DexelGrid zmap;
  removal::TriDexel tri;
  removal::NeedleSet needles;
  std::vector<Eigen::Vector3d> needle_point, needle_normal;  // nominal points and normals (N-buffer)
  double needle_half = 1.0;

  std::size_t rays() const {
    if (vdb) return 0;
    switch (kind) {
      case core::RemovalSpec::Field::ZMap: return static_cast<std::size_t>(zmap.nu()) * zmap.nv();
      case core::RemovalSpec::Field::TriDexel:
        return static_cast<std::size_t>(tri.x.nu()) * tri.x.nv() + static_cast<std::size_t>(tri.y.nu()) * tri.y.nv() +
               static_cast<std::size_t>(tri.z.nu()) * tri.z.nv();
      case core::RemovalSpec::Field::NBuffer: return needles.size();
    }
    return 0;
  }
  std::size_t memory_bytes() const {
    if (vdb) return part.memory_bytes();
    switch (kind) {
      case core::RemovalSpec::Field::ZMap: return zmap.memory_bytes();
      case core::RemovalSpec::Field::TriDexel: return tri.x.memory_bytes() + tri.y.memory_bytes() + tri.z.memory_bytes();
      case core::RemovalSpec::Field::NBuffer: return needles.store().memory_bytes();
    }
    return 0;
  }
};

void read_needles(const core::Job& job, Field& f) {
  const auto& file = job.removal.needles_file;
  std::ifstream in(file);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  std::string line;
  int lineno = 0;
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty() || line[0] == '#' || std::isalpha(static_cast<unsigned char>(line[0]))) continue;
    double v[6];
    std::stringstream ss(line);
    std::string cell;
    int c = 0;
    while (c < 6 && std::getline(ss, cell, ',')) {
      char* end = nullptr;
      v[c] = std::strtod(cell.c_str(), &end);
      if (end == cell.c_str() || !std::isfinite(v[c]))
        throw core::Error(core::located(file.string(), lineno, "expected x,y,z,nx,ny,nz numbers (mm)"));
      ++c;
    }
    if (c != 6) throw core::Error(core::located(file.string(), lineno, "expected 6 values x,y,z,nx,ny,nz"));
    const Eigen::Vector3d p(v[0], v[1], v[2]), n(v[3], v[4], v[5]);
    if (n.norm() < 1e-9) throw core::Error(core::located(file.string(), lineno, "the normal has zero length"));
    f.needle_point.push_back(p);
    f.needle_normal.push_back(n.normalized());
    o.push_back(p - job.removal.needle_half_length_mm * n.normalized());
    d.push_back(n.normalized());
    len.push_back(2 * job.removal.needle_half_length_mm);
  }
  if (o.empty()) throw core::Error(file.string() + ": no needles");
  f.needles = removal::NeedleSet(std::move(o), std::move(d), std::move(len));
  f.needle_half = job.removal.needle_half_length_mm;
}

void fill_stock(Field& f, const core::Job& job, const std::optional<core::TriangleMesh>& mesh) {
  if (mesh) {
    // One dexelizer: the closedness check and Embree's tree once for every grid.
    const removal::MeshDexelizer dex(*mesh, job.stock.mesh_file.string());
    switch (f.kind) {
      case core::RemovalSpec::Field::ZMap: dex.fill(f.zmap); break;
      case core::RemovalSpec::Field::TriDexel:
        for (removal::DexelGrid* g : {&f.tri.x, &f.tri.y, &f.tri.z}) dex.fill(*g);
        break;
      case core::RemovalSpec::Field::NBuffer: dex.fill(f.needles); break;
    }
    return;
  }
  const removal::Box b{job.stock.min_mm, job.stock.max_mm};
  switch (f.kind) {
    case core::RemovalSpec::Field::ZMap: removal::fill_box(f.zmap, b); break;
    case core::RemovalSpec::Field::TriDexel:
      for (removal::DexelGrid* g : {&f.tri.x, &f.tri.y, &f.tri.z}) removal::fill_box(*g, b);
      break;
    case core::RemovalSpec::Field::NBuffer: removal::fill_box(f.needles, b); break;
  }
}

void cut_field(Field& f, const std::vector<removal::SweptTool>& sweeps) {
  if (f.vdb) {
    f.part.cut(sweeps);
    return;
  }
  switch (f.kind) {
    case core::RemovalSpec::Field::ZMap: removal::cut(f.zmap, sweeps); break;
    case core::RemovalSpec::Field::TriDexel:
      for (removal::DexelGrid* g : {&f.tri.x, &f.tri.y, &f.tri.z}) removal::cut(*g, sweeps);
      break;
    case core::RemovalSpec::Field::NBuffer: removal::cut(f.needles, sweeps); break;
  }
}

std::vector<removal::SweptTool> sweeps_of(const core::Job& job, const removal::PoseTrack& tr) {
  removal::TrackOptions topt;
  topt.tolerance_mm = track_tolerance(job, track_turns(tr));
  return removal::sweeps_from_track(removal::make_tool(job.tool), tr, topt).sweeps;
}

Field initial_field(const core::Job& job, double feed_scale, Progress& progress, std::set<std::string>& chain);

// The part a job leaves: its stock, cut by its own motion.
Field final_field(const core::Job& job, Progress& progress, std::set<std::string>& chain) {
  Field f = initial_field(job, 1.0, progress, chain);
  const Motion m = simulate_motion(job, 1.0, job.removal.motion, progress);
  progress.stage(job.name + ": material removal");
  cut_field(f, sweeps_of(job, track_of(m, job, job.removal.motion)));
  progress.done();
  return f;
}

// A job's starting field: a box or mesh stock, or the part another job leaves (run here, recursively).
Field initial_field(const core::Job& job, double feed_scale, Progress& progress, std::set<std::string>& chain) {
  const std::string key = std::filesystem::weakly_canonical(job.file).string();
  if (!chain.insert(key).second) throw core::Error(job.file.string() + ": the stock jobs form a cycle");
  Field f;
  if (job.stock.kind == core::StockSpec::Kind::Job) {
    Field prev = final_field(core::load_job(job.stock.job_file), progress, chain);
    if (prev.vdb != (job.removal.method == core::RemovalSpec::Method::Vdb))
      throw core::Error(job.file.string() + ": [removal] method differs from that of the stock job " +
                        job.stock.job_file.string() + " (a part is carried from job to job in one kernel)");
    return prev;
  }
  (void)feed_scale;
  std::optional<core::TriangleMesh> mesh;
  removal::Box region;
  if (job.stock.kind == core::StockSpec::Kind::Box) {
    region = removal::Box{job.stock.min_mm, job.stock.max_mm};
  } else if (job.stock.kind == core::StockSpec::Kind::Mesh) {
    mesh = core::read_stl(job.stock.mesh_file);
    region.lo = mesh->vertices_mm.colwise().minCoeff().transpose();
    region.hi = mesh->vertices_mm.colwise().maxCoeff().transpose();
  } else {
    throw core::Error(job.file.string() + ": [stock] is required to remove material (box, stl or job)");
  }
  f.kind = job.removal.field;
  f.region = region;
  f.spacing_mm = job.removal.spacing_mm;
  if (job.removal.method == core::RemovalSpec::Method::Vdb) {
    f.vdb = true;
    if (f.kind == core::RemovalSpec::Field::NBuffer) read_needles(job, f);
    // The memory it will need, stated before the run (removal/vdb_part.hpp's model): the narrow band of the stock's
    // surface, which cuts that finish a part replace by their own (deep cuts add their new walls and floors), and
    // the part mesh written at the end. report.json holds both beside the level set's measured memory.
    const removal::SurfaceArea sa = mesh ? removal::surface_area(*mesh) : removal::surface_area(region);
    const double h = job.removal.voxel_mm;
    f.vdb_estimate_bytes = removal::estimate_level_set_bytes(sa, h);
    f.vdb_mesh_estimate_bytes = removal::estimate_mesh_bytes(sa.area_mm2, h);
    std::fprintf(stderr, "%s: level set at %g mm voxels, estimated memory %.1f MB: %.1f MB for the band of the stock's "
                 "%.0f mm^2 (%.1f MB per 1000 mm^2 of surface the cuts add) and %.1f MB for the part mesh\n",
                 job.name.c_str(), h, (f.vdb_estimate_bytes + f.vdb_mesh_estimate_bytes) / 1e6,
                 f.vdb_estimate_bytes / 1e6, sa.area_mm2, f.vdb_estimate_bytes / sa.area_mm2 * 1e3 / 1e6,
                 f.vdb_mesh_estimate_bytes / 1e6);
    const double limit = 32e9;
    if (f.vdb_estimate_bytes + f.vdb_mesh_estimate_bytes > limit)
      throw core::Error(job.file.string() + fmt::format(": [removal] voxel_mm = {} needs about {:.1f} GB for the level "
                                                        "set and its mesh; choose a larger voxel", h,
                                                        (f.vdb_estimate_bytes + f.vdb_mesh_estimate_bytes) / 1e9));
    progress.stage(job.name + ": stock (level set)");
    removal::VdbOptions vo;
    vo.voxel_mm = h;
    f.part = mesh ? removal::VdbPart::mesh(*mesh, vo, job.stock.mesh_file.string())
                  : removal::VdbPart::box(region, vo);
    progress.done();
    return f;
  }
  const double rays_limit = 4e8;  // ~3.2 GB of dexels: far beyond this machine's jobs, a typo in spacing_mm
  const Eigen::Vector3d ext = region.hi - region.lo;
  const double estimate = (ext.x() / f.spacing_mm + 1) * (ext.y() / f.spacing_mm + 1) *
                          (f.kind == core::RemovalSpec::Field::TriDexel ? 3 : 1);
  if (f.kind != core::RemovalSpec::Field::NBuffer && estimate > rays_limit)
    throw core::Error(job.file.string() + fmt::format(": [removal] spacing_mm = {} gives {:.3g} rays ({:.1f} GB); "
                                                      "choose a larger spacing",
                                                      f.spacing_mm, estimate, estimate * 8 / 1e9));
  switch (f.kind) {
    case core::RemovalSpec::Field::ZMap: f.zmap = removal::make_zmap(region, f.spacing_mm); break;
    case core::RemovalSpec::Field::TriDexel: f.tri = removal::make_tridexel(region, f.spacing_mm); break;
    case core::RemovalSpec::Field::NBuffer: read_needles(job, f); break;
  }
  progress.stage(job.name + ": stock");
  fill_stock(f, job, mesh);
  progress.done();
  return f;
}

// Surface of a grid field (z-map, or the tri-dexel's Z grid).
core::HeightGrid surface_of(const Field& f) {
  // The level set read back along the z-map's rays (same nodes as a z-map at spacing_mm).
  if (f.vdb) return f.part.height_grid(f.region, f.spacing_mm);
  return removal::height_grid(f.kind == core::RemovalSpec::Field::TriDexel ? f.tri.z : f.zmap);
}

// Along each needle, the surface's position relative to the nominal point (mm along the normal; NaN if empty).
Eigen::VectorXd needle_offsets(const Field& f) {
  Eigen::VectorXd o(static_cast<Eigen::Index>(f.needles.size()));
  if (f.vdb) {
    const std::vector<double> top = f.part.needle_tops(f.needles);
    for (std::size_t k = 0; k < top.size(); ++k) o[static_cast<Eigen::Index>(k)] = top[k] - f.needle_half;
    return o;
  }
  for (std::size_t k = 0; k < f.needles.size(); ++k) o[static_cast<Eigen::Index>(k)] = f.needles.store().top(k) - f.needle_half;
  return o;
}

}  // namespace

int run_run(const RunArgs& args) {
  const auto t_start = Clock::now();
  const core::Job job = core::load_job(args.job);
  if (job.gain_schedule_file && args.feed_scale.value_or(1.0) != 1.0)
    throw core::Error(job.file.string() + ": --feed-scale changes the setpoints its gain_schedule was computed for "
                      "(run vmsim oga on a job at those feeds instead)");
  // The picture options are checked now, not after the simulation.
  ImageArgs image_args;
  image_args.size = args.image_size;
  const ImageOptions image_opt = args.no_render ? ImageOptions{} : image_options(image_args);
  Progress progress(!args.quiet);
  std::set<std::string> chain;

  auto t0 = Clock::now();
  Field field = initial_field(job, 1.0, progress, chain);
  const double t_stock = seconds_since(t0);
  const Field start = field;  // the stock this job starts from (reference "stock")

  const double feed_scale = args.feed_scale.value_or(1.0);
  Motion motion = simulate_motion(job, feed_scale, job.removal.motion, progress);
  if (motion.response) {
    t0 = Clock::now();
    const auto kin = core::make_kinematics(job.machine);
    const core::Setpoints& sp = motion.interp.setpoints;
    Eigen::MatrixXd cmd(motion.response->samples(), 3), act(motion.response->samples(), 3);
    for (Eigen::Index k = 0; k < cmd.rows(); ++k) {
      cmd.row(k) = kin->forward(sp.position.row(std::min(k, sp.samples() - 1)).transpose(), tlo_at(motion, k)).tip_mm.transpose();
      act.row(k) = kin->forward(motion.response->position.row(k).transpose(), tlo_at(motion, k)).tip_mm.transpose();
    }
    motion.contour = core::contour_error(cmd, act);
    motion.timings["contour_error"] = seconds_since(t0);
  }

  t0 = Clock::now();
  progress.stage(job.name + ": material removal");
  const removal::PoseTrack track = track_of(motion, job, job.removal.motion);
  removal::TrackOptions topt;
  topt.tolerance_mm = track_tolerance(job, track_turns(track));
  const removal::TrackSweeps ts = removal::sweeps_from_track(removal::make_tool(job.tool), track, topt);
  cut_field(field, ts.sweeps);
  progress.done();
  const double t_cut = seconds_since(t0);

  // The reference surface.
  t0 = Clock::now();
  std::optional<Field> ref;
  std::string ref_name = "none";
  if (job.reference.kind == core::ReferenceSpec::Kind::Job) {
    std::set<std::string> ref_chain = {std::filesystem::weakly_canonical(job.file).string()};
    ref = final_field(core::load_job(job.reference.job_file), progress, ref_chain);
    ref_name = "job: the part " + job.reference.job_file.filename().string() + " leaves";
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Feed) {
    ref = start;
    const Motion rm = simulate_motion(job, feed_scale * job.reference.feed_scale, job.removal.motion, progress);
    progress.stage(job.name + ": reference (feeds x " + fmt::format("{:g}", job.reference.feed_scale) + ")");
    cut_field(*ref, sweeps_of(job, track_of(rm, job, job.removal.motion)));
    progress.done();
    ref_name = fmt::format("feed: the same program through the same chain at {:g} x its feeds", job.reference.feed_scale);
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Stock) {
    ref = start;
    ref_name = "stock: the part " + job.stock.job_file.filename().string() + " leaves";
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Program) {
    progress.stage(job.name + ": reference (programmed path)");
    ref = start;
    const Motion pm = simulate_motion(job, feed_scale, core::RemovalSpec::Motion::Program, progress);
    cut_field(*ref, sweeps_of(job, track_of(pm, job, core::RemovalSpec::Motion::Program)));
    progress.done();
    ref_name = "program: the same program cut exactly along its programmed path";
  }
  const double t_ref = seconds_since(t0);

  // Outputs.
  t0 = Clock::now();
  const std::filesystem::path dir = args.out_dir.value_or(std::filesystem::current_path());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
  std::vector<std::string> files;
  nlohmann::json marks_json = nlohmann::json::array();
  std::vector<metrology::Mark> marks;
  nlohmann::json surface_json;
  ResultData images;  // what the pictures are drawn from
  // Method "vdb", and tri-dexel fields (converted to a level set, removal/vdb_from_dexels.cpp): the part as a
  // watertight, manifold mesh of its level set (volumeToMesh), each vertex with its signed distance to the reference
  // part's level set (positive: material left; NaN beyond the reference's band of 3 voxels), and the level set
  // itself as part.vdb.
  nlohmann::json vdb_json;
  auto write_level_set_part = [&](const removal::VdbPart& part, const removal::VdbPart* ref_part) {
    core::TriangleMesh mesh = part.mesh(job.removal.mesh_adaptivity);
    std::size_t beyond = 0;
    if (ref_part) {
      Eigen::VectorXd dev = ref_part->signed_distance(mesh.vertices_mm);
      for (Eigen::Index k = 0; k < dev.size(); ++k) beyond += std::isnan(dev[k]) ? 1 : 0;
      mesh.point_data.emplace_back("deviation_mm", std::move(dev));
    }
    core::write_stl_binary(dir / "part.stl", mesh);
    render::write_vtp(dir / "part.vtp", mesh);
    part.write_vdb(dir / "part.vdb");
    files.insert(files.end(), {"part.stl", "part.vtp", "part.vdb"});
    vdb_json = {{"voxel_mm", part.voxel_mm()}, {"mesh_triangles", mesh.triangles.rows()},
                {"mesh_vertices", mesh.vertices_mm.rows()}, {"mesh_adaptivity", job.removal.mesh_adaptivity},
                {"volume_mm3", part.volume_mm3()}};
    if (ref_part) vdb_json["vertices_beyond_reference_band"] = beyond;
  };
  auto write_vdb_part = [&]() { write_level_set_part(field.part, ref && ref->vdb ? &ref->part : nullptr); };
  if (field.kind != core::RemovalSpec::Field::NBuffer) {
    const core::HeightGrid pred = surface_of(field);
    metrology::write_height_csv(dir / "surface.csv", pred);
    metrology::write_height_npy(dir / "surface.npy", pred);
    files.insert(files.end(), {"surface.csv", "surface.npy", "surface.npy.json"});
    // X3P (ISO 5436-2) for metrology tools: MountainsMap, Gwyddion, vmsim compare.
    metrology::X3pWriteOptions x3p;
    x3p.version = std::string("vmsim ") + VMSIM_VERSION;
    x3p.comment = "predicted surface of job " + job.name;
    metrology::write_x3p(dir / "surface.x3p", pred, x3p);
    files.push_back("surface.x3p");
    std::optional<core::HeightGrid> dev;
    if (ref) {
      const core::HeightGrid rs = surface_of(*ref);
      dev = metrology::deviation(pred, rs);
      metrology::write_height_csv(dir / "reference.csv", rs);
      metrology::write_height_csv(dir / "deviation.csv", *dev);
      metrology::write_height_npy(dir / "deviation.npy", *dev);
      files.insert(files.end(), {"reference.csv", "deviation.csv", "deviation.npy", "deviation.npy.json"});
      x3p.comment = "reference surface of job " + job.name + " (" + ref_name + ")";
      metrology::write_x3p(dir / "reference.x3p", rs, x3p);
      x3p.comment = "deviation of job " + job.name + ": predicted - reference (negative: overcut)";
      metrology::write_x3p(dir / "deviation.x3p", *dev, x3p);
      files.insert(files.end(), {"reference.x3p", "deviation.x3p"});
      marks = metrology::find_marks(*dev, 1e-3);  // marks deeper than 1 um
    }
    images.surface = pred;
    images.deviation = dev;
    surface_json = {{"grid", {{"x0_mm", pred.x0_mm}, {"y0_mm", pred.y0_mm}, {"dx_mm", pred.dx_mm}, {"dy_mm", pred.dy_mm},
                              {"nx", pred.nx()}, {"ny", pred.ny()}}}};
    if (field.vdb) {
      write_vdb_part();
      surface_json["mesh_triangles"] = vdb_json["mesh_triangles"];
    } else if (field.kind == core::RemovalSpec::Field::TriDexel) {
      // The tri-dexel part in 3-D (walls and undercuts the height grid cannot show), through its level set.
      const removal::VdbPart lp = removal::VdbPart::from_tridexel(field.tri);
      std::optional<removal::VdbPart> rl;
      if (ref && !ref->vdb && ref->kind == core::RemovalSpec::Field::TriDexel) rl = removal::VdbPart::from_tridexel(ref->tri);
      write_level_set_part(lp, rl ? &*rl : nullptr);
      surface_json["mesh_triangles"] = vdb_json["mesh_triangles"];
      surface_json["tridexel_mesh"] = vdb_json;
    } else {
      const core::TriangleMesh mesh = removal::heightfield_mesh(pred, field.region.lo.z(), dev ? &*dev : nullptr);
      core::write_stl_binary(dir / "part.stl", mesh);
      render::write_vtp(dir / "part.vtp", mesh);
      files.insert(files.end(), {"part.stl", "part.vtp"});
      surface_json["mesh_triangles"] = mesh.triangles.rows();
    }
    if (dev) {
      const double lo = dev->z_mm.isNaN().select(0, dev->z_mm).minCoeff();
      const double hi = dev->z_mm.isNaN().select(0, dev->z_mm).maxCoeff();
      surface_json["deviation_min_mm"] = lo;
      surface_json["deviation_max_mm"] = hi;
    }
  } else {
    const Eigen::VectorXd pred = needle_offsets(field);
    const Eigen::VectorXd rs = ref ? needle_offsets(*ref) : Eigen::VectorXd::Constant(pred.size(), NAN);
    core::AtomicFile out(dir / "needles.csv");
    out.stream() << "x_mm,y_mm,z_mm,nx,ny,nz,surface_offset_mm,reference_offset_mm,deviation_mm\n";
    double worst = 0, lo = INFINITY, hi = -INFINITY;
    std::size_t worst_k = 0, empty = 0;
    for (std::size_t k = 0; k < field.needles.size(); ++k) {
      const auto kk = static_cast<Eigen::Index>(k);
      const double d = pred[kk] - rs[kk];
      if (std::isfinite(d) && std::abs(d) > std::abs(worst)) worst = d, worst_k = k;
      if (std::isfinite(d)) lo = std::min(lo, d), hi = std::max(hi, d);
      if (!std::isfinite(pred[kk])) ++empty;
      const Eigen::Vector3d& p = field.needle_point[k];
      const Eigen::Vector3d& n = field.needle_normal[k];
      out.stream() << fmt::format("{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.7f},{:.7f},{:.7f}\n", p.x(), p.y(),
                                  p.z(), n.x(), n.y(), n.z(), pred[kk], rs[kk], d);
    }
    out.commit();
    files.push_back("needles.csv");
    if (field.vdb) write_vdb_part();
    // The needles' summary, as the grid fields give theirs: how many, how many the tool emptied (the surface lies
    // beyond their inner end), and the extremes of the deviation (overcuts negative).
    surface_json = {{"needles", field.needles.size()}, {"empty_needles", empty}};
    if (lo <= hi) {
      surface_json["deviation_min_mm"] = lo;
      surface_json["deviation_max_mm"] = hi;
    }
    if (std::abs(worst) > 1e-3) {
      metrology::Mark m;
      m.depth_mm = std::abs(worst);
      m.overcut = worst < 0;
      m.x_mm = field.needle_point[worst_k].x();
      m.y_mm = field.needle_point[worst_k].y();
      marks.push_back(m);
    }
  }
  for (const metrology::Mark& m : marks)
    marks_json.push_back({{"depth_mm", m.depth_mm}, {"kind", m.overcut ? "overcut" : "undercut"}, {"x_mm", m.x_mm},
                          {"y_mm", m.y_mm}, {"x_extent_mm", m.x_extent_mm}, {"y_extent_mm", m.y_extent_mm},
                          {"area_mm2", m.area_mm2}});
  if (motion.response && motion.contour) {
    images.signals = motion_signals(job, motion.program, motion.interp.setpoints, *motion.response, *motion.contour,
                                    feed_scale);
    write_signals(dir / "signals.csv", *images.signals);
    files.push_back("signals.csv");
  }
  const double t_write = seconds_since(t0);

  // Pictures, after every result file: a failure to draw loses no result.
  std::optional<std::string> render_error;
  double t_render = 0;
  std::size_t n_images = 0;
  if (!args.no_render) {
    t0 = Clock::now();
    progress.stage(job.name + ": pictures");
    images.job = job.name;
    images.reference = ref_name;
    images.marks = marks;
    try {
      for (const std::string& f : write_result_images(images, dir / "images", image_opt)) {
        files.push_back("images/" + f);
        ++n_images;
      }
    } catch (const core::Error& e) {
      render_error = e.what();
    }
    progress.done();
    t_render = seconds_since(t0);
  }

  nlohmann::json report = report_header("run", job);
  report["removal"] = {{"method", field.vdb ? "vdb" : "dexel"},
                       {"field", field.kind == core::RemovalSpec::Field::ZMap       ? "zmap"
                                 : field.kind == core::RemovalSpec::Field::TriDexel ? "tridexel"
                                                                                     : "nbuffer"},
                       {"spacing_mm", field.spacing_mm},
                       {"rays", field.rays()},
                       {"memory_bytes", field.memory_bytes()},
                       {"motion", motion_name(job.removal.motion)},
                       {"track_points", ts.points},
                       {"sweeps", ts.sweeps.size()},
                       {"track_tolerance_mm", topt.tolerance_mm},
                       {"track_error_bound_mm", ts.error_bound_mm},
                       {"tool_axis_turns", track.axis_per_sample.rows() > 0},
                       {"orientation_error_mm", ts.orientation_error_mm}};
  if (field.vdb) {
    report["removal"]["voxel_mm"] = job.removal.voxel_mm;
    report["removal"]["memory_estimate_bytes"] = field.vdb_estimate_bytes;  // the level set's, vs memory_bytes
    report["removal"]["mesh_memory_estimate_bytes"] = field.vdb_mesh_estimate_bytes;
    report["removal"]["active_voxels"] = field.part.active_voxels();
    report["removal"]["level_set"] = vdb_json;
  }
  report["reference"] = ref_name;
  if (job.gain_schedule_file) report["gain_schedule"] = job.gain_schedule_file->string();
  if (job.axis_models_file) report["axis_models"] = job.axis_models_file->string();
  report["marks"] = marks_json;
  report["surface"] = surface_json;
  if (job.removal.motion != core::RemovalSpec::Motion::Program)
    report["interpolation"] = {{"cycle_time_s", motion.interp.stats.cycle_time_s},
                               {"setpoints", motion.interp.setpoints.samples()},
                               {"period_s", motion.interp.setpoints.period_s}};
  if (motion.response) {
    // Follow-up error of every axis (seed 004 section 4 reports the rotary axes' in degrees) and of the tool axis.
    const auto kin = core::make_kinematics(job.machine);
    report["axis_following_error"] =
        axis_following_json(job.machine, motion.interp.setpoints, motion.response->position, kin.get(),
                            [&](Eigen::Index k) { return tlo_at(motion, k); });
  }
  std::optional<ContourStats> cutting;
  if (motion.contour) {
    cutting = cutting_contour_stats(*motion.contour, motion.interp.setpoints, motion.program);
    report["contour_error"] = contour_json(*motion.contour, *cutting);
  }
  report["files"] = files;
  nlohmann::json timings = motion.timings;
  timings["stock"] = t_stock;
  timings["removal"] = t_cut;
  timings["reference"] = t_ref;
  timings["write"] = t_write;
  if (!args.no_render) timings["render"] = t_render;
  if (render_error) report["render_error"] = *render_error;
  timings["total"] = seconds_since(t_start);
  report["timings_s"] = timings;
  write_report(dir / "report.json", report);
  files.push_back("report.json");

  if (field.vdb)
    std::printf("job %s: %s motion, %zu sweeps on a level set of %zu voxels at %g mm (%.1f MB, estimated %.1f MB)\n",
                job.name.c_str(), motion_name(job.removal.motion), ts.sweeps.size(), field.part.active_voxels(),
                job.removal.voxel_mm, field.memory_bytes() / 1e6, field.vdb_estimate_bytes / 1e6);
  else
    std::printf("job %s: %s motion, %zu sweeps on %zu rays (%.1f MB)\n", job.name.c_str(),
                motion_name(job.removal.motion), ts.sweeps.size(), field.rays(), field.memory_bytes() / 1e6);
  if (cutting)
    std::printf("contour error on cutting moves: max %.2f um, rms %.2f um\n", cutting->max_abs_mm * 1e3,
                cutting->rms_mm * 1e3);
  std::printf("reference: %s\n", ref_name.c_str());
  if (ref && marks.empty()) std::printf("marks: none deeper than 1 um\n");
  for (std::size_t k = 0; k < marks.size() && k < 5; ++k) {
    const metrology::Mark& m = marks[k];
    std::printf("mark %zu: %s %.2f um at x %.3f y %.3f, %.3f x %.3f mm\n", k + 1, m.overcut ? "overcut " : "undercut",
                m.depth_mm * 1e3, m.x_mm, m.y_mm, m.x_extent_mm, m.y_extent_mm);
  }
  if (n_images > 0) std::printf("images: %s (%zu PNG files)\n", (dir / "images").string().c_str(), n_images);
  std::printf("wrote %s (%zu files) in %.1f s\n", dir.string().c_str(), files.size(), seconds_since(t_start));
  if (render_error)
    throw core::Error("the results are written to " + dir.string() + ", but the pictures could not be drawn "
                      "(--no-render skips them): " + *render_error);
  return 0;
}

}  // namespace vmsim::app
