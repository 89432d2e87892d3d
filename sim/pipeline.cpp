// vmsim run's chain as callable stages (app/run_pipeline.hpp): the motion, its sweeps, the stock's field cut by
// them, the reference field, and the surfaces read back.
#include "sim/pipeline.hpp"
#include "core/timing.hpp"
#include "sim/cut_progress.hpp"
#include "sim/motion_stream.hpp"

#include "sim/job_program.hpp"
#include "sim/tool_poses.hpp"
#include "sim/tools.hpp"
#include "core/arc.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "motion/kinematics.hpp"
#include "core/memory.hpp"
#include "core/stl.hpp"
#include "core/units.hpp"
#include "removal/mesh_stock.hpp"
#include "removal/surface.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

namespace vmsim::sim {

namespace {
using Clock = std::chrono::steady_clock;
using core::seconds_since;
}  // namespace

const char* motion_name(core::RemovalSpec::Motion m) {
  switch (m) {
    case core::RemovalSpec::Motion::Actual:
      return "actual";
    case core::RemovalSpec::Motion::Setpoints:
      return "setpoints";
    case core::RemovalSpec::Motion::Program:
      return "program";
  }
  return "?";
}

void read_and_interpolate(const Chain& chain, core::RemovalSpec::Motion kind, Motion& m, core::Progress& progress) {
  const core::Job& job = chain.job();
  auto t0 = Clock::now();
  m.program = read_job_program(job);
  (void)move_tools(job, m.program);  // a tool the job does not describe fails here, before any motion is computed
  m.timings["read_program"] = seconds_since(t0);
  if (kind == core::RemovalSpec::Motion::Program) return;
  t0 = Clock::now();
  progress.stage(job.name + ": interpolation");
  m.interp = chain.interpolate(m.program);
  progress.done();
  m.timings["interpolate"] = seconds_since(t0);
}

Motion simulate_motion(const Chain& chain, core::RemovalSpec::Motion kind, core::Progress& progress) {
  const core::Job& job = chain.job();
  Motion m;
  read_and_interpolate(chain, kind, m, progress);
  if (kind == core::RemovalSpec::Motion::Program) return m;
  m.tool_length_offset_mm = tool_length_offsets(m.program, m.interp.setpoints);
  if (kind == core::RemovalSpec::Motion::Actual) {
    const auto t0 = Clock::now();
    progress.stage(job.name + ": servo drives");
    m.response = chain.simulate(m.interp.setpoints, false, &m.drive_checks);
    progress.done();
    m.timings["drives"] = seconds_since(t0);
  }
  return m;
}

void add_contour_error(Motion& motion, const core::Job& job) {
  if (!motion.response) return;
  const auto t0 = Clock::now();
  const auto kin = motion::make_kinematics(job.machine);
  const core::Setpoints& sp = motion.interp.setpoints;
  Eigen::MatrixXd cmd(motion.response->samples(), 3), act(motion.response->samples(), 3);
  for (Eigen::Index k = 0; k < cmd.rows(); ++k) {
    cmd.row(k) =
        kin->forward(sp.position.row(std::min(k, sp.samples() - 1)).transpose(), tlo_at(motion, k)).tip_mm.transpose();
    act.row(k) = kin->forward(motion.response->position.row(k).transpose(), tlo_at(motion, k)).tip_mm.transpose();
  }
  motion.contour = motion::contour_error(cmd, act);
  motion.timings["contour_error"] = seconds_since(t0);
}

double tlo_at(const Motion& m, Eigen::Index k) {
  if (m.tool_length_offset_mm.size() == 0) {  // a streamed motion: from the move indices, as tool_length_offsets
    const Eigen::ArrayXi& mi = m.interp.setpoints.move_index;
    const int i = mi[std::min(k, mi.size() - 1)];
    return i >= 0 ? m.program.moves[static_cast<std::size_t>(i)].tool_length_offset_mm : 0.0;
  }
  return m.tool_length_offset_mm[std::min(k, m.tool_length_offset_mm.size() - 1)];
}

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

removal::PoseTrack track_of(const Motion& m, const core::Job& job, core::RemovalSpec::Motion kind) {
  removal::PoseTrack tr;
  if (kind == core::RemovalSpec::Motion::Program && job.machine.kinematics == "chain" &&
      program_turns_tool(m.program)) {
    // A five-axis program: tool tip and axis along the programmed moves (app/tool_poses.hpp), sampled within a tenth
    // of the track tolerance as the arcs below are.
    const auto kin = motion::make_kinematics(job.machine);
    // Each move sampled with the reach of the tool that cuts it, each pose tagged with that tool.
    const std::vector<int> per_move = job.tools.empty() ? std::vector<int>{} : move_tools(job, m.program);
    return program_pose_track(m.program, motion::toolpath_in_axis_space(m.program, job.machine), *kin, job.machine,
                              cutting_tools(job), per_move, 0.1 * track_tolerance(job, true));
  }
  if (kind == core::RemovalSpec::Motion::Program) {
    // The programmed geometry itself: line ends, and arcs sampled finely enough that their chords stay within a
    // tenth of the track tolerance (the kernel's sweeps are exact between points).
    std::vector<Eigen::Vector3d> pts;
    // Each point's tool: its move's (the first point, the first move's start, too).
    const std::vector<int> per_move = job.tools.empty() ? std::vector<int>{} : move_tools(job, m.program);
    if (!m.program.moves.empty()) pts.push_back(m.program.moves.front().start.head<3>());
    if (!per_move.empty()) tr.tool.push_back(per_move.front());
    for (std::size_t mi = 0; mi < m.program.moves.size(); ++mi) {
      const core::Move& mv = m.program.moves[mi];
      if (mv.kind == core::MotionKind::Line) {
        pts.push_back(mv.end.head<3>());
      } else {
        const core::ArcFrame arc = core::arc_frame(mv, m.program.source_path);
        const int n = arc.chords(0.1 * job.removal.track_tolerance_mm);
        for (int k = 1; k <= n; ++k) pts.push_back(arc.point_at(double(k) / n).head<3>());
      }
      if (!per_move.empty()) tr.tool.resize(pts.size(), per_move[mi]);
    }
    tr.tip_mm.resize(static_cast<Eigen::Index>(pts.size()), 3);
    for (std::size_t k = 0; k < pts.size(); ++k) tr.tip_mm.row(static_cast<Eigen::Index>(k)) = pts[k].transpose();
    return tr;
  }
  const auto kin = motion::make_kinematics(job.machine);
  const core::Setpoints& sp = m.interp.setpoints;
  const bool actual = kind == core::RemovalSpec::Motion::Actual;
  const Eigen::MatrixXd& axes = actual ? m.response->position : sp.position;
  // Tool tip and axis per sample through the forward transform (a turning axis on five-axis machines). Between Te
  // samples of the actual motion the tip follows the cubic through both samples with the drives' velocities through
  // the chain's Jacobian (Cartesian machine: the X Y Z velocities).
  removal::PoseTrack tr_axes = pose_track_from_axes(*kin, job.machine, axes, actual ? &m.response->velocity : nullptr,
                                                    sp.period_s, [&](Eigen::Index k) { return tlo_at(m, k); });
  tr_axes.tool = sample_tools(job, m, tr_axes.tip_mm.rows());
  return tr_axes;
}

std::size_t Field::rays() const {
  if (vdb) return 0;
  switch (kind) {
    case core::RemovalSpec::Field::ZMap:
      return static_cast<std::size_t>(zmap.nu()) * zmap.nv();
    case core::RemovalSpec::Field::TriDexel:
      return static_cast<std::size_t>(tri.x.nu()) * tri.x.nv() + static_cast<std::size_t>(tri.y.nu()) * tri.y.nv() +
             static_cast<std::size_t>(tri.z.nu()) * tri.z.nv();
    case core::RemovalSpec::Field::NBuffer:
      return needles.size();
  }
  return 0;
}
std::size_t Field::memory_bytes() const {
  if (vdb) return part.memory_bytes();
  switch (kind) {
    case core::RemovalSpec::Field::ZMap:
      return zmap.memory_bytes();
    case core::RemovalSpec::Field::TriDexel:
      return tri.x.memory_bytes() + tri.y.memory_bytes() + tri.z.memory_bytes();
    case core::RemovalSpec::Field::NBuffer:
      return needles.store().memory_bytes();
  }
  return 0;
}

std::vector<removal::DexelGrid*> Field::grids() {
  if (vdb) return {};
  if (kind == core::RemovalSpec::Field::ZMap) return {&zmap};
  if (kind == core::RemovalSpec::Field::TriDexel) return {&tri.x, &tri.y, &tri.z};
  return {};
}
std::vector<const removal::DexelGrid*> Field::grids() const {
  std::vector<const removal::DexelGrid*> out;
  for (removal::DexelGrid* g : const_cast<Field*>(this)->grids()) out.push_back(g);
  return out;
}

namespace {

void read_needles(const core::Job& job, Field& f) {
  const auto& file = job.removal.needles_file;
  // Columns x,y,z,nx,ny,nz (mm) by name under a header row (others are ignored), or the first six without one.
  core::CsvReader in(file, core::CsvReader::Header::Optional);
  std::size_t col[6] = {0, 1, 2, 3, 4, 5};
  if (in.has_header()) {
    static constexpr const char* kNames[6] = {"x", "y", "z", "nx", "ny", "nz"};
    for (int c = 0; c < 6; ++c) col[c] = static_cast<std::size_t>(in.require(kNames[c]));
  }
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  while (in.next()) {
    if (!in.has_header() && in.cells() != 6)
      throw in.error(fmt::format("{} values, expected 6: x,y,z,nx,ny,nz (mm)", in.cells()));
    double v[6];
    for (int c = 0; c < 6; ++c) v[c] = in.number(col[c]);
    const Eigen::Vector3d p(v[0], v[1], v[2]), n(v[3], v[4], v[5]);
    if (n.norm() < 1e-9) throw in.error("the normal has zero length");
    f.needle_point.push_back(p);
    f.needle_normal.push_back(n.normalized());
  }
  if (f.needle_point.empty()) throw core::Error(file.string() + ": no needles");
  f.needle_half = job.removal.needle_half_length_mm;
  // The tile's needles: whole blocks of the list (the store's rows).
  const std::size_t n = f.needle_point.size(), block = removal::NeedleSet::kBlock;
  std::size_t k0 = 0, k1 = n;
  if (!f.tile.whole()) {
    const auto [b0, b1] = removal::tile_rows(static_cast<int>((n + block - 1) / block), f.tile);
    k0 = static_cast<std::size_t>(b0) * block;
    k1 = std::min(n, static_cast<std::size_t>(b1) * block);
  }
  for (std::size_t k = k0; k < k1; ++k) {
    o.push_back(f.needle_point[k] - f.needle_half * f.needle_normal[k]);
    d.push_back(f.needle_normal[k]);
    len.push_back(2 * f.needle_half);
  }
  f.needle_first = k0;
  f.needles = removal::NeedleSet(std::move(o), std::move(d), std::move(len));
}

void fill_stock(Field& f, const core::Job& job, const std::optional<core::TriangleMesh>& mesh) {
  if (mesh) {
    // One dexelizer: the closedness check and Embree's tree once for every grid.
    const removal::MeshDexelizer dex(*mesh, job.stock.mesh_file.string());
    switch (f.kind) {
      case core::RemovalSpec::Field::ZMap:
        dex.fill(f.zmap);
        break;
      case core::RemovalSpec::Field::TriDexel:
        for (removal::DexelGrid* g : {&f.tri.x, &f.tri.y, &f.tri.z}) dex.fill(*g);
        break;
      case core::RemovalSpec::Field::NBuffer:
        dex.fill(f.needles);
        break;
    }
    return;
  }
  const removal::Box b{job.stock.min_mm, job.stock.max_mm};
  switch (f.kind) {
    case core::RemovalSpec::Field::ZMap:
      removal::fill_box(f.zmap, b);
      break;
    case core::RemovalSpec::Field::TriDexel:
      for (removal::DexelGrid* g : {&f.tri.x, &f.tri.y, &f.tri.z}) removal::fill_box(*g, b);
      break;
    case core::RemovalSpec::Field::NBuffer:
      removal::fill_box(f.needles, b);
      break;
  }
}

}  // namespace

namespace {
// `done` counts the sweeps times grids cut so far over the whole field (the progress' total), across tool runs.
std::size_t cut_field_one_tool(Field& f, const std::vector<removal::SweptTool>& sweeps, core::Progress* progress,
                               std::size_t& done) {
  if (f.vdb) {
    f.part.cut(sweeps);
    return sweeps.size();
  }
  if (f.kind == core::RemovalSpec::Field::NBuffer) {
    // The needle kernel already takes each block of needles with the sweeps whose boxes meet the block's box; the
    // count says how many reach the tile's needles at all.
    removal::cut(f.needles, sweeps);
    if (f.tile.whole()) return sweeps.size();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
    for (std::size_t k = 0; k < f.needles.size(); ++k) {
      const Eigen::Vector3d a = f.needles.origin(k), e = a + f.needles.length(k) * f.needles.direction(k);
      lo = lo.cwiseMin(a.cwiseMin(e)), hi = hi.cwiseMax(a.cwiseMax(e));
    }
    std::size_t reach = 0;
    for (const removal::SweptTool& s : sweeps) {
      Eigen::Vector3d a, b;
      s.bounds(a, b);
      reach += (b.array() >= lo.array()).all() && (a.array() <= hi.array()).all();
    }
    return reach;
  }
  if (f.tile.whole()) {
    if (!progress) {
      for (removal::DexelGrid* g : f.grids()) removal::cut(*g, sweeps);
      return sweeps.size();
    }
    // One call per grid, which reports between bands of rows: batches of sweeps would let the kernel take each block's
    // sweeps lowest first only within a batch (flower_mold: 1.5x the cut's CPU in batches of 4096).
    for (removal::DexelGrid* g : f.grids()) {
      removal::cut(*g, sweeps, progress, static_cast<double>(done));
      done += sweeps.size();
    }
    return sweeps.size();
  }
  // A tile: each grid's band of rows only with the sweeps that reach it.
  std::vector<char> reaches(sweeps.size(), 0);
  for (removal::DexelGrid* g : f.grids()) {
    std::vector<removal::SweptTool> mine;
    for (std::size_t k = 0; k < sweeps.size(); ++k)
      if (!removal::footprint(*g, sweeps[k]).empty()) mine.push_back(sweeps[k]), reaches[k] = 1;
    removal::cut(*g, mine);
  }
  return static_cast<std::size_t>(std::count(reaches.begin(), reaches.end(), 1));
}

bool same_tool(const removal::Tool& a, const removal::Tool& b) {
  return a.radius_mm == b.radius_mm && a.corner_radius_mm == b.corner_radius_mm && a.length_mm == b.length_mm;
}
}  // namespace

std::size_t cut_field(Field& f, const std::vector<removal::SweptTool>& sweeps) { return cut_field(f, sweeps, nullptr); }

std::size_t cut_field(Field& f, const std::vector<removal::SweptTool>& sweeps, core::Progress* progress) {
  // One kernel call per run of consecutive sweeps of one tool (a program with tool changes), in program order.
  std::size_t a = 0, reach = 0, done = 0;
  while (a < sweeps.size()) {
    std::size_t b = a + 1;
    while (b < sweeps.size() && same_tool(sweeps[b].tool, sweeps[a].tool)) ++b;
    if (a == 0 && b == sweeps.size()) return cut_field_one_tool(f, sweeps, progress, done);  // one tool: no copy
    reach += cut_field_one_tool(f,
                                std::vector<removal::SweptTool>(sweeps.begin() + static_cast<std::ptrdiff_t>(a),
                                                                sweeps.begin() + static_cast<std::ptrdiff_t>(b)),
                                progress, done);
    a = b;
  }
  return reach;
}

std::size_t cut_field(Field& f, const removal::TrackSweeps& ts, core::Progress* progress, ToolMap& map) {
  if (f.vdb || f.kind == core::RemovalSpec::Field::NBuffer || !f.tile.whole())
    throw core::Error("the tool map needs a whole z-map or tri-dexel field (not a level set, needles or a tile)");
  removal::DexelGrid& z = f.kind == core::RemovalSpec::Field::TriDexel ? f.tri.z : f.zmap;
  map.nu = z.nu(), map.nv = z.nv();
  map.cell_mm2 = z.du() * z.dv();
  const std::size_t n = static_cast<std::size_t>(map.nu) * static_cast<std::size_t>(map.nv);
  map.tool.assign(n, ToolMap::kUncut);
  std::vector<double> before(n);
  auto tops = [&](std::vector<double>& t) {
    for (int j = 0; j < z.nv(); ++j)
      for (int i = 0; i < z.nu(); ++i) t[z.ray(i, j)] = z.top(i, j);
  };
  std::size_t reach = 0, done = 0, covered = 0;
  for (const removal::TrackSweeps::Run& r : ts.runs) {
    if (r.tool < 0 || r.tool >= ToolMap::kUncut || r.first != covered || r.first + r.count > ts.sweeps.size())
      throw core::Error(fmt::format("the tool map: run of tool {} over sweeps [{}, +{}) does not follow the last",
                                    r.tool, r.first, r.count));
    covered += r.count;
    tops(before);
    reach += cut_field_one_tool(
        f,
        std::vector<removal::SweptTool>(ts.sweeps.begin() + static_cast<std::ptrdiff_t>(r.first),
                                        ts.sweeps.begin() + static_cast<std::ptrdiff_t>(r.first + r.count)),
        progress, done);
    for (int j = 0; j < z.nv(); ++j)
      for (int i = 0; i < z.nu(); ++i) {
        // Lowered: material was there and its top is now lower, or the ray is now empty.
        const double b = before[z.ray(i, j)], a = z.top(i, j);
        if (std::isfinite(b) && !(a >= b)) map.tool[z.ray(i, j)] = static_cast<std::uint8_t>(r.tool);
      }
  }
  if (covered != ts.sweeps.size())
    throw core::Error(fmt::format("the tool map: the runs cover {} of {} sweeps", covered, ts.sweeps.size()));
  return reach;
}

removal::TrackSweeps sweeps_of(const core::Job& job, const removal::PoseTrack& tr) {
  removal::TrackOptions topt;
  topt.tolerance_mm = track_tolerance(job, track_turns(tr));
  // The stock's bounding box holds all the material: a turning tool's sub-steps count only its engaging length
  // (track.hpp). A mesh stock's is its mesh's (read again here: a few ms for the parts' meshes, beside the sweeps).
  if (const std::optional<removal::Box> box = stock_box(job)) topt.material_box = Eigen::AlignedBox3d(box->lo, box->hi);
  return removal::sweeps_from_track(cutting_tools(job), tr, topt);
}

removal::Box mesh_box(const core::TriangleMesh& mesh) {
  return removal::Box{mesh.vertices_mm.colwise().minCoeff().transpose(),
                      mesh.vertices_mm.colwise().maxCoeff().transpose()};
}

std::optional<removal::Box> stock_box(const core::Job& job) {
  if (job.stock.kind == core::StockSpec::Kind::Box) return removal::Box{job.stock.min_mm, job.stock.max_mm};
  if (job.stock.kind != core::StockSpec::Kind::Mesh) return std::nullopt;
  const core::TriangleMesh mesh = core::read_stl(job.stock.mesh_file);
  if (mesh.vertices_mm.rows() == 0) return std::nullopt;
  return mesh_box(mesh);
}

removal::PoseTrack motion_track(const Chain& chain, core::RemovalSpec::Motion kind, core::Progress& progress) {
  if (kind == core::RemovalSpec::Motion::Actual) {
    // Streamed (sim/motion_stream.hpp): the drives' response is never held whole; the track is the same.
    Motion m;
    StreamOptions so;
    so.figures = false;
    return stream_actual_motion(chain, m, so, progress).track;
  }
  const Motion m = simulate_motion(chain, kind, progress);
  return track_of(m, chain.job(), kind);
}

Field final_field(const core::Job& job, core::Progress& progress, std::set<std::string>& chain, const Tile& tile) {
  Field f = initial_field(job, progress, chain, tile);
  const removal::PoseTrack track = motion_track(Chain(job), job.removal.motion, progress);
  progress.stage(job.name + ": material removal");
  cut_field(f, sweeps_of(job, track).sweeps);
  progress.done();
  return f;
}

Field initial_field(const core::Job& job, core::Progress& progress, std::set<std::string>& chain, const Tile& tile) {
  const std::string key = std::filesystem::weakly_canonical(job.file).string();
  if (!chain.insert(key).second) throw core::Error(job.file.string() + ": the stock jobs form a cycle");
  Field f;
  if (job.stock.kind == core::StockSpec::Kind::Job) {
    Field prev = final_field(core::load_job(job.stock.job_file), progress, chain, tile);
    if (prev.vdb != (job.removal.method == core::RemovalSpec::Method::Vdb))
      throw core::Error(job.file.string() + ": [removal] method differs from that of the stock job " +
                        job.stock.job_file.string() + " (a part is carried from job to job in one kernel)");
    return prev;
  }
  std::optional<core::TriangleMesh> mesh;
  removal::Box region;
  if (job.stock.kind == core::StockSpec::Kind::Box) {
    region = removal::Box{job.stock.min_mm, job.stock.max_mm};
  } else if (job.stock.kind == core::StockSpec::Kind::Mesh) {
    mesh = core::read_stl(job.stock.mesh_file);
    // Before its bounding box: a mesh without triangles has none (it crashed here, issue 18).
    core::check_closed(*mesh, job.stock.mesh_file.string());
    region = mesh_box(*mesh);
  } else {
    throw core::Error(job.file.string() + ": [stock] is required to remove material (box, stl or job)");
  }
  f.kind = job.removal.field;
  f.tile = tile;
  f.region = region;
  f.spacing_mm = job.removal.spacing_mm;
  if (job.removal.method == core::RemovalSpec::Method::Vdb) {
    if (!tile.whole())
      throw core::Error(job.file.string() +
                        ": [removal] method = \"vdb\" does not run tiled under MPI (a narrow-band "
                        "level set has no rows to split without changing its result); run it as one process, or use "
                        "method = \"dexel\"");
    f.vdb = true;
    if (f.kind == core::RemovalSpec::Field::NBuffer) read_needles(job, f);
    // The memory it will need, stated before the run (removal/vdb_part.hpp's model): the narrow band of the stock's
    // surface, which cuts that finish a part replace by their own (deep cuts add their new walls and floors), and
    // the part mesh written at the end. report.json holds both beside the level set's measured memory.
    const removal::SurfaceArea sa = mesh ? removal::surface_area(*mesh) : removal::surface_area(region);
    const double h = job.removal.voxel_mm;
    f.vdb_estimate_bytes = removal::estimate_level_set_bytes(sa, h);
    f.vdb_mesh_estimate_bytes = removal::estimate_mesh_bytes(sa.area_mm2, h);
    std::fprintf(stderr,
                 "%s: level set at %g mm voxels, estimated memory %.1f MB: %.1f MB for the band of the stock's "
                 "%.0f mm^2 (%.1f MB per 1000 mm^2 of surface the cuts add) and %.1f MB for the part mesh\n",
                 job.name.c_str(), h, (f.vdb_estimate_bytes + f.vdb_mesh_estimate_bytes) / 1e6,
                 f.vdb_estimate_bytes / 1e6, sa.area_mm2, f.vdb_estimate_bytes / sa.area_mm2 * 1e3 / 1e6,
                 f.vdb_mesh_estimate_bytes / 1e6);
    // Against the memory this machine (or its control group) has left, not a fixed constant (issue 18).
    const core::AvailableMemory avail = core::available_memory();
    const double limit = std::isfinite(avail.bytes) ? avail.bytes : 32e9;
    if (f.vdb_estimate_bytes + f.vdb_mesh_estimate_bytes > limit)
      throw core::Error(job.file.string() +
                        fmt::format(": [removal] voxel_mm = {} needs about {} for the level "
                                    "set and its mesh, while {} is available ({}); choose a "
                                    "larger voxel_mm",
                                    h, core::format_bytes(f.vdb_estimate_bytes + f.vdb_mesh_estimate_bytes),
                                    core::format_bytes(limit), avail.source.empty() ? "a fixed limit" : avail.source));
    progress.stage(job.name + ": stock (level set)");
    removal::VdbOptions vo;
    vo.voxel_mm = h;
    f.part = mesh ? removal::VdbPart::mesh(*mesh, vo, job.stock.mesh_file.string()) : removal::VdbPart::box(region, vo);
    progress.done();
    return f;
  }
  // ~3.2 GB of dexels per process: far beyond this machine's jobs, a typo in spacing_mm (a tiled run holds its share).
  const double rays_limit = 4e8;
  const Eigen::Vector3d ext = region.hi - region.lo;
  // A tri-dexel field's three grids: XY, YZ and XZ (the stock's height counts).
  const double nx = ext.x() / f.spacing_mm + 1, ny = ext.y() / f.spacing_mm + 1, nz = ext.z() / f.spacing_mm + 1;
  const double estimate =
      (f.kind == core::RemovalSpec::Field::TriDexel ? nx * ny + ny * nz + nx * nz : nx * ny) / tile.count;
  if (f.kind != core::RemovalSpec::Field::NBuffer) {
    // The field, the stock copy a run keeps for its reference, and the outputs on the height grid's nodes
    // (sim/memory_plan.hpp's model: 8 B per ray and copy, 136 B per node), against the memory available.
    const double bytes = estimate * 8.0 * 2 + (tile.whole() ? nx * ny * 136.0 : 0.0);
    const core::AvailableMemory avail = core::available_memory();
    if (bytes > avail.bytes)
      throw core::Error(job.file.string() +
                        fmt::format(": [removal] spacing_mm = {} gives {:.3g} rays{} which with the outputs need at "
                                    "least {}, while {} is available ({}); choose a larger spacing_mm{}",
                                    f.spacing_mm, estimate, tile.whole() ? "" : " per process",
                                    core::format_bytes(bytes), core::format_bytes(avail.bytes), avail.source,
                                    " or more processes (vmsim run --plan JOB says how many)"));
  }
  if (f.kind != core::RemovalSpec::Field::NBuffer && estimate > rays_limit)
    throw core::Error(job.file.string() + fmt::format(": [removal] spacing_mm = {} gives {:.3g} rays ({:.1f} GB){}; "
                                                      "choose a larger spacing{}",
                                                      f.spacing_mm, estimate, estimate * 8 / 1e9,
                                                      tile.whole() ? "" : " per process",
                                                      " or more processes (vmsim run --plan JOB says how many)"));
  try {
    switch (f.kind) {
      case core::RemovalSpec::Field::ZMap:
        f.zmap = removal::make_zmap(region, f.spacing_mm, tile);
        break;
      case core::RemovalSpec::Field::TriDexel:
        f.tri = removal::make_tridexel(region, f.spacing_mm, tile);
        break;
      case core::RemovalSpec::Field::NBuffer:
        read_needles(job, f);
        break;
    }
  } catch (const core::Error& e) {
    if (tile.whole()) throw;
    throw core::Error(job.file.string() + ": [removal] the stock's rays split into " + std::to_string(tile.count) +
                      " tiles: " + e.what());
  }
  progress.stage(job.name + ": stock");
  fill_stock(f, job, mesh);
  progress.done();
  return f;
}

core::HeightGrid surface_of(const Field& f) {
  // The level set read back along the z-map's rays (same nodes as a z-map at spacing_mm).
  if (f.vdb) return f.part.height_grid(f.region, f.spacing_mm);
  return removal::height_grid(f.kind == core::RemovalSpec::Field::TriDexel ? f.tri.z : f.zmap);
}

Eigen::VectorXd needle_offsets(const Field& f) {
  Eigen::VectorXd o(static_cast<Eigen::Index>(f.needles.size()));
  if (f.vdb) {
    const std::vector<double> top = f.part.needle_tops(f.needles);
    for (std::size_t k = 0; k < top.size(); ++k) o[static_cast<Eigen::Index>(k)] = top[k] - f.needle_half;
    return o;
  }
  for (std::size_t k = 0; k < f.needles.size(); ++k)
    o[static_cast<Eigen::Index>(k)] = f.needles.store().top(k) - f.needle_half;
  return o;
}

Reference reference_field(const core::Job& job, const Field& start, double feed_scale, core::Progress& progress) {
  Reference r;
  std::optional<Field>& ref = r.field;
  std::string& ref_name = r.name;
  if (job.reference.kind == core::ReferenceSpec::Kind::Job) {
    std::set<std::string> ref_chain = {std::filesystem::weakly_canonical(job.file).string()};
    ref = final_field(core::load_job(job.reference.job_file), progress, ref_chain, start.tile);
    ref_name = "job: the part " + job.reference.job_file.filename().string() + " leaves";
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Feed) {
    ref = start;
    ChainOptions copt;
    copt.feed_scale = feed_scale * job.reference.feed_scale;
    copt.ignore_gain_schedule = copt.feed_scale != 1.0;  // the schedule's gains are for the job's own feeds
    const removal::PoseTrack track = motion_track(Chain(job, copt), job.removal.motion, progress);
    progress.stage(job.name + ": reference (feeds x " + fmt::format("{:g}", job.reference.feed_scale) + ")");
    cut_field(*ref, sweeps_of(job, track).sweeps);
    progress.done();
    ref_name =
        fmt::format("feed: the same program through the same chain at {:g} x its feeds", job.reference.feed_scale);
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Stock) {
    ref = start;
    ref_name = "stock: the part " + job.stock.job_file.filename().string() + " leaves";
  } else if (job.reference.kind == core::ReferenceSpec::Kind::Program) {
    progress.stage(job.name + ": reference (programmed path)");
    ref = start;
    const Motion pm = simulate_motion(Chain(job), core::RemovalSpec::Motion::Program, progress);
    cut_field(*ref, sweeps_of(job, track_of(pm, job, core::RemovalSpec::Motion::Program)).sweeps);
    progress.done();
    ref_name = "program: the same program cut exactly along its programmed path";
  }
  return r;
}

}  // namespace vmsim::sim
