#include "sim/run.hpp"
#include "sim/cut_progress.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"
#include "core/units.hpp"
#include "metrology/grid_io.hpp"
#include "motion/kinematics.hpp"
#include "removal/surface.hpp"
#include "sim/contour_stats.hpp"
#include "sim/motion_stream.hpp"
#include "sim/part_mesh.hpp"
#include "sim/report.hpp"
#include "sim/tools.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <set>
#include <string>

namespace vmsim::sim {

namespace {

using core::Clock;
using core::process_cpu_s;
using core::seconds_since;

// A reference with at least this fraction of its nodes steeper than metrology::kSteepWallSlopeDeg is said to
// have steep walls (a warning): 1 %, so that a few nodes on a pocket's rim do not warn on every flat part.
constexpr double kSteepWallWarnFraction = 0.01;

const char* field_name(const Field& f) {
  return f.kind == core::RemovalSpec::Field::ZMap       ? "zmap"
         : f.kind == core::RemovalSpec::Field::TriDexel ? "tridexel"
                                                        : "nbuffer";
}

// The level set's part as a watertight, manifold mesh (volumeToMesh), each vertex with its signed distance to the
// reference part's level set (positive: material left; NaN beyond the reference's band of 3 voxels).
LevelSetPart level_set_part(removal::VdbPart part, const removal::VdbPart* ref_part, double adaptivity) {
  LevelSetPart out;
  out.mesh = part.mesh(adaptivity);
  std::size_t beyond = 0;
  if (ref_part) {
    Eigen::VectorXd dev = ref_part->signed_distance(out.mesh.vertices_mm);
    for (Eigen::Index k = 0; k < dev.size(); ++k) beyond += std::isnan(dev[k]) ? 1 : 0;
    out.mesh.point_data.emplace_back("deviation_mm", std::move(dev));
  }
  out.figures = {{"voxel_mm", part.voxel_mm()},
                 {"mesh_triangles", out.mesh.triangles.rows()},
                 {"mesh_vertices", out.mesh.vertices_mm.rows()},
                 {"mesh_adaptivity", adaptivity},
                 {"volume_mm3", part.volume_mm3()}};
  if (ref_part) out.figures["vertices_beyond_reference_band"] = beyond;
  out.part = std::move(part);
  return out;
}

// Where the reference has steep walls, what its height grid means there and which fields resolve them.
core::Warning steep_wall_warning(const Field& field, const metrology::SteepWalls& walls, double step_mm) {
  core::Warning w;
  w.code = "steep_walls";
  w.subject = "removal.field";
  w.message = fmt::format(
      "{:.1f} % of the reference surface ({} nodes) is steeper than {:g} deg: the {} height grid's deviation there "
      "is reported along the reference's normal (surface.deviation_along; the vertical figure is "
      "deviation_vertical), to first order and within about the spacing ({:g} mm) where a wall falls between "
      "nodes{}. The part mesh of a tri-dexel field (removal.field = \"tridexel\") or a level set (removal.method = "
      "\"vdb\") follows the walls themselves, each vertex with its signed distance to the reference part.",
      100.0 * walls.fraction, walls.nodes, metrology::kSteepWallSlopeDeg, field_name(field), field.spacing_mm,
      step_mm > 0
          ? fmt::format("; the part mesh's faces can be up to {:.3f} mm off them (surface.mesh_wall_step_max_mm)",
                        step_mm)
          : std::string());
  return w;
}

// Grid fields: heights, reference, deviation (along the reference's normal, and vertical), marks, and the part mesh.
void read_back_grids(const core::Job& job, RunResult& r, nlohmann::json& surface_json, core::Warnings& warnings) {
  const Field& field = r.cut.field;
  const std::optional<Field>& ref = r.cut.reference.field;
  r.surface = surface_of(field);
  const core::HeightGrid& pred = *r.surface;
  metrology::SteepWalls walls;
  if (ref) {
    r.reference_surface = surface_of(*ref);
    r.deviation_vertical = metrology::deviation(pred, *r.reference_surface);
    const metrology::Slope slope = metrology::slope_of(*r.reference_surface);
    r.deviation = metrology::normal_deviation(*r.deviation_vertical, slope);
    r.marks = metrology::find_marks(*r.deviation, 1e-3);  // marks deeper than 1 um along the normal
    metrology::add_vertical(r.marks, *r.deviation_vertical, slope);
    walls = metrology::steep_walls(slope);
  }
  surface_json = {{"grid",
                   {{"x0_mm", pred.x0_mm},
                    {"y0_mm", pred.y0_mm},
                    {"dx_mm", pred.dx_mm},
                    {"dy_mm", pred.dy_mm},
                    {"nx", pred.nx()},
                    {"ny", pred.ny()}}}};
  if (field.vdb) {
    r.level_set = level_set_part(field.part, ref && ref->vdb ? &ref->part : nullptr, job.removal.mesh_adaptivity);
    surface_json["mesh_triangles"] = r.level_set->figures["mesh_triangles"];
  } else if (field.kind == core::RemovalSpec::Field::TriDexel) {
    // The tri-dexel part in 3-D (walls and undercuts the height grid cannot show), through its level set.
    std::optional<removal::VdbPart> rl;
    if (ref && !ref->vdb && ref->kind == core::RemovalSpec::Field::TriDexel)
      rl = removal::VdbPart::from_tridexel(ref->tri);
    r.level_set =
        level_set_part(removal::VdbPart::from_tridexel(field.tri), rl ? &*rl : nullptr, job.removal.mesh_adaptivity);
    surface_json["mesh_triangles"] = r.level_set->figures["mesh_triangles"];
    surface_json["tridexel_mesh"] = r.level_set->figures;
  } else {
    r.part_mesh_triangles = heightfield_mesh_triangles(pred);  // the mesh itself on request: grid_part_mesh
    surface_json["mesh_triangles"] = r.part_mesh_triangles;
    // The height-field mesh's error bound between nodes on walls (it interpolates straight across them).
    surface_json["mesh_wall_step_max_mm"] = metrology::wall_step_max_mm(pred);
  }
  if (r.deviation) {
    const core::HeightGrid& dev = *r.deviation;
    const core::HeightGrid& vert = *r.deviation_vertical;
    surface_json["deviation_along"] = "normal";
    surface_json["deviation_min_mm"] = dev.z_mm.isNaN().select(0, dev.z_mm).minCoeff();
    surface_json["deviation_max_mm"] = dev.z_mm.isNaN().select(0, dev.z_mm).maxCoeff();
    surface_json["deviation_vertical_min_mm"] = vert.z_mm.isNaN().select(0, vert.z_mm).minCoeff();
    surface_json["deviation_vertical_max_mm"] = vert.z_mm.isNaN().select(0, vert.z_mm).maxCoeff();
    surface_json["steep_walls"] = {
        {"slope_deg", metrology::kSteepWallSlopeDeg}, {"nodes", walls.nodes}, {"fraction", walls.fraction}};
    if (walls.fraction >= kSteepWallWarnFraction)
      warnings.push_back(steep_wall_warning(field, walls, surface_json.value("mesh_wall_step_max_mm", 0.0)));
  }
}

// N-buffer fields: each needle's offset, its reference and deviation, and the deepest deviation as the mark.
void read_back_needles(const core::Job& job, RunResult& r, nlohmann::json& surface_json) {
  const Field& field = r.cut.field;
  const std::optional<Field>& ref = r.cut.reference.field;
  r.needle_offset_mm = needle_offsets(field);
  const Eigen::Index n = r.needle_offset_mm.size();
  r.needle_reference_mm = ref ? needle_offsets(*ref) : Eigen::VectorXd::Constant(n, NAN);
  r.needle_deviation_mm = r.needle_offset_mm - r.needle_reference_mm;
  double worst = 0, lo = INFINITY, hi = -INFINITY;
  Eigen::Index worst_k = 0;
  std::size_t empty = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double d = r.needle_deviation_mm[k];
    if (std::isfinite(d) && std::abs(d) > std::abs(worst)) worst = d, worst_k = k;
    if (std::isfinite(d)) lo = std::min(lo, d), hi = std::max(hi, d);
    if (!std::isfinite(r.needle_offset_mm[k])) ++empty;
  }
  if (field.vdb)
    r.level_set = level_set_part(field.part, ref && ref->vdb ? &ref->part : nullptr, job.removal.mesh_adaptivity);
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
    m.x_mm = field.needle_point[static_cast<std::size_t>(worst_k)].x();
    m.y_mm = field.needle_point[static_cast<std::size_t>(worst_k)].y();
    r.marks.push_back(m);
  }
}

nlohmann::json removal_json(const core::Job& job, const Cut& c) {
  const Field& field = c.field;
  nlohmann::json j = {{"method", field.vdb ? "vdb" : "dexel"},
                      {"field", field_name(field)},
                      {"spacing_mm", field.spacing_mm},
                      {"rays", field.rays()},
                      {"memory_bytes", field.memory_bytes()},
                      {"motion", motion_name(job.removal.motion)},
                      {"track_points", c.sweeps.points},
                      {"sweeps", c.sweeps.sweeps.size()},
                      {"track_tolerance_mm", c.track_tolerance_mm},
                      {"track_error_bound_mm", c.sweeps.error_bound_mm},
                      {"tool_axis_turns", c.track.axis_per_sample.rows() > 0},
                      {"orientation_error_mm", c.sweeps.orientation_error_mm}};
  if (field.vdb) {
    j["voxel_mm"] = job.removal.voxel_mm;
    j["memory_estimate_bytes"] = field.vdb_estimate_bytes;  // the level set's, vs memory_bytes
    j["mesh_memory_estimate_bytes"] = field.vdb_mesh_estimate_bytes;
    j["active_voxels"] = field.part.active_voxels();
  }
  return j;
}

}  // namespace

namespace {
// The cut, and with several tools on a whole grid field the map of which tool last cut where (a single tool's run
// is the plain cut, unchanged).
std::size_t cut_with_map(const core::Job& job, Cut& c, core::Progress& progress) {
  const bool grid = !c.field.vdb && c.field.kind != core::RemovalSpec::Field::NBuffer && c.field.tile.whole();
  if (!grid || job_tools(job).size() < 2) return cut_field(c.field, c.sweeps.sweeps, &progress);
  c.tool_map.emplace();
  return cut_field(c.field, c.sweeps, &progress, *c.tool_map);
}
}  // namespace

Cut cut_job(const core::Job& job, const RunOptions& options, core::Progress& progress) {
  ChainOptions copt;
  copt.feed_scale = options.feed_scale;
  const Chain chain(job, copt);  // first: refuses a feed scale with a gain schedule before any work
  Cut c;
  std::set<std::string> stock_chain;
  auto t0 = Clock::now();
  c.field = initial_field(job, progress, stock_chain, options.tile);
  c.timings["stock"] = seconds_since(t0);
  const Field start = c.field;  // the stock this job starts from (reference "stock")

  if (job.removal.motion == core::RemovalSpec::Motion::Actual) {
    // The actual motion streamed (sim/motion_stream.hpp): the drives' response is consumed block by block; the
    // track's tip velocity is released once the sweeps are made, before the contour error needs its memory.
    StreamOptions so;
    so.feed_scale = options.feed_scale;
    MotionStream stream = stream_actual_motion(chain, c.motion, so, progress);
    t0 = Clock::now();
    double cpu0 = process_cpu_s();
    progress.stage(job.name + ": material removal");
    c.track = std::move(stream.track);
    c.track_tolerance_mm = track_tolerance(job, track_turns(c.track));
    c.sweeps = sweeps_of(job, c.track);
    double removal_s = seconds_since(t0), removal_cpu = process_cpu_s() - cpu0;
    c.track.tip_velocity_mm_per_s.resize(0, 3);
    finish_streamed_motion(c.motion, stream, c.track.tip_mm);
    c.track.tip_mm.resize(0, 3);  // the report needs only whether the tool axis turns
    for (const auto& [k, v] : c.motion.timings.items()) c.timings[k] = v;
    t0 = Clock::now();
    cpu0 = process_cpu_s();
    progress.stage(job.name + ": material removal",
                   static_cast<double>(c.sweeps.sweeps.size() * std::max<std::size_t>(1, c.field.grids().size())));
    c.sweeps_in_tile = cut_with_map(job, c, progress);
    progress.done();
    c.timings["removal"] = removal_s + seconds_since(t0);
    c.timings["removal_cpu"] = removal_cpu + process_cpu_s() - cpu0;  // every thread's CPU time
  } else {
    // Setpoints or the programmed path: no drives, so no contour error, signals or following error.
    c.motion = simulate_motion(chain, job.removal.motion, progress);
    for (const auto& [k, v] : c.motion.timings.items()) c.timings[k] = v;

    t0 = Clock::now();
    const double cpu0 = process_cpu_s();
    progress.stage(job.name + ": material removal");
    c.track = track_of(c.motion, job, job.removal.motion);
    c.track_tolerance_mm = track_tolerance(job, track_turns(c.track));
    c.sweeps = sweeps_of(job, c.track);
    // The sweeps times the grids: cut_field reports them done, and the terminal turns that into the time left.
    progress.stage(job.name + ": material removal",
                   static_cast<double>(c.sweeps.sweeps.size() * std::max<std::size_t>(1, c.field.grids().size())));
    c.sweeps_in_tile = cut_with_map(job, c, progress);
    progress.done();
    c.timings["removal"] = seconds_since(t0);
    c.timings["removal_cpu"] = process_cpu_s() - cpu0;  // every thread's CPU time
  }

  t0 = Clock::now();
  c.reference = reference_field(job, start, options.feed_scale, progress);
  c.timings["reference"] = seconds_since(t0);
  return c;
}

RunResult finish_run(const core::Job& job, Cut cut, core::Progress& progress) {
  RunResult r;
  r.cut = std::move(cut);
  const Cut& c = r.cut;
  const auto t0 = Clock::now();
  progress.stage(job.name + ": surfaces");
  nlohmann::json surface_json;
  core::Warnings warnings = c.motion.drive_checks.warnings;
  if (c.field.kind != core::RemovalSpec::Field::NBuffer)
    read_back_grids(job, r, surface_json, warnings);
  else
    read_back_needles(job, r, surface_json);
  r.signals = c.motion.signals;  // an actual motion's, binned while it streamed (sim/motion_stream.hpp)
  progress.done();

  nlohmann::json& report = r.report;
  report = report_header("run", job);
  report["removal"] = removal_json(job, c);
  if (r.level_set && c.field.vdb) report["removal"]["level_set"] = r.level_set->figures;
  report["reference"] = c.reference.name;
  if (job.gain_schedule_file) report["gain_schedule"] = job.gain_schedule_file->string();
  if (job.axis_models_file) report["axis_models"] = job.axis_models_file->string();
  report["tools"] = tools_json(job, c);
  // Each grid mark's tool: the one whose sweep made the surface at its deepest point (sim/tools.hpp says why).
  const std::vector<int> mark_tool =
      r.surface ? mark_tools(c, r.marks, *r.surface, c.field.vdb ? 0.5 * job.removal.voxel_mm : 1e-4)
                : std::vector<int>(r.marks.size(), -1);
  nlohmann::json marks_json = nlohmann::json::array();
  for (std::size_t k = 0; k < r.marks.size(); ++k) {
    const metrology::Mark& m = r.marks[k];
    marks_json.push_back({{"depth_mm", m.depth_mm},
                          {"kind", m.overcut ? "overcut" : "undercut"},
                          {"x_mm", m.x_mm},
                          {"y_mm", m.y_mm},
                          {"x_extent_mm", m.x_extent_mm},
                          {"y_extent_mm", m.y_extent_mm},
                          {"area_mm2", m.area_mm2}});
    if (std::isfinite(m.depth_vertical_mm)) {
      // depth_mm is along the reference's normal; the vertical figure and the slope where the mark is deepest.
      marks_json.back()["depth_vertical_mm"] = m.depth_vertical_mm;
      marks_json.back()["slope_deg"] = m.slope_rad * 180.0 / core::units::kPi;
      marks_json.back()["steep_wall"] = m.steep_wall;
    }
    if (mark_tool[k] >= 0) marks_json.back()["tool"] = tool_label(job, mark_tool[k]);
  }
  report["marks"] = marks_json;
  report["surface"] = surface_json;
  const Motion& motion = c.motion;
  if (job.removal.motion != core::RemovalSpec::Motion::Program)
    report["interpolation"] = {{"cycle_time_s", motion.interp.stats.cycle_time_s},
                               {"setpoints", motion.interp.setpoints.samples()},
                               {"period_s", motion.interp.setpoints.period_s}};
  // Follow-up error of every axis (the feed-drive simulation paper section 4 reports the rotary axes' in degrees) and
  // of the tool axis, taken while the actual motion streamed.
  if (motion.response) report["axis_following_error"] = motion.axis_following;
  if (motion.contour)
    report["contour_error"] =
        contour_json(*motion.contour, cutting_contour_stats(*motion.contour, motion.interp.setpoints, motion.program));
  if (motion.response) report["drive_checks"] = motion.drive_checks.axes;
  add_verdict(report, warnings);
  report["timings_s"] = c.timings;
  report["timings_s"]["surfaces"] = seconds_since(t0);
  return r;
}

core::TriangleMesh grid_part_mesh(const RunResult& r) {
  if (r.part_mesh) return *r.part_mesh;
  if (!r.surface) throw core::Error("grid_part_mesh: the run has no height grid (an N-buffer field)");
  return removal::heightfield_mesh(*r.surface, r.cut.field.region.lo.z(), r.deviation ? &*r.deviation : nullptr);
}

RunResult run_job(const core::Job& job, const RunOptions& options, core::Progress& progress) {
  return finish_run(job, cut_job(job, options, progress), progress);
}

}  // namespace vmsim::sim
