// vmsim run JOB: the whole chain. Program -> interpolator -> drives -> kinematics -> material removal -> surfaces,
// and the marks: the signed deviation of the predicted surface from the reference surface.
#include "sim/axis_following.hpp"
#include "app/commands.hpp"
#include "sim/contour_stats.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "app/result_images.hpp"
#include "sim/pipeline.hpp"
#include "sim/signals.hpp"
#include "app/run_plan.hpp"
#include "app/tiled_run.hpp"
#include "app/mpi_session.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "motion/kinematics.hpp"
#include "core/stl.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/marks.hpp"
#include "metrology/x3p.hpp"
#include "removal/surface.hpp"
#include "render/mesh_io.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <set>

namespace vmsim::app {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
// --tiles-out, rank 0: report.json without the whole-part results (marks, meshes, pictures need the whole grid):
// the motion's figures, the removal's, and every rank's tile.
int write_tiles_report(const core::Job& job, const RunArgs& args, const std::filesystem::path& dir, const sim::Field& field,
                       const sim::Reference& reference, const sim::Motion& motion, const removal::TrackSweeps& ts,
                       const nlohmann::json& tiles_json, Clock::time_point t_start) {
  nlohmann::json report = report_header("run", job);
  double rays = 0;
  for (const auto& r : tiles_json["per_rank"]) rays += r["rays"].get<double>();
  report["removal"] = {{"method", "dexel"},
                       {"field", field.kind == core::RemovalSpec::Field::ZMap ? "zmap" : "tridexel"},
                       {"spacing_mm", field.spacing_mm},
                       {"rays", rays},
                       {"motion", sim::motion_name(job.removal.motion)},
                       {"sweeps", ts.sweeps.size()},
                       {"track_tolerance_mm", job.removal.track_tolerance_mm},
                       {"track_error_bound_mm", ts.error_bound_mm}};
  report["tiles"] = tiles_json;
  report["tiles"]["manifest"] = "tiles.json";
  report["reference"] = reference.name;
  if (motion.contour) {
    const sim::ContourStats cutting = sim::cutting_contour_stats(*motion.contour, motion.interp.setpoints, motion.program);
    report["contour_error"] = sim::contour_json(*motion.contour, cutting);
  }
  if (job.removal.motion != core::RemovalSpec::Motion::Program)
    report["interpolation"] = {{"cycle_time_s", motion.interp.stats.cycle_time_s},
                               {"setpoints", motion.interp.setpoints.samples()},
                               {"period_s", motion.interp.setpoints.period_s}};
  report["files"] = {"tiles.json", "report.json"};
  report["timings_s"] = {{"total", seconds_since(t_start)}};
  write_report(dir / "report.json", report);
  std::printf("job %s: %s motion, %zu sweeps on %.0f rays in %d tiles\n", job.name.c_str(),
              sim::motion_name(job.removal.motion), ts.sweeps.size(), rays, tiles_json["ranks"].get<int>());
  std::printf("wrote %s: tiles.json, report.json and tiles/ (one X3P per rank%s) in %.1f s\n", dir.string().c_str(),
              reference.field ? ", surface and deviation" : "", seconds_since(t_start));
  (void)args;
  return 0;
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
  if (args.plan) return run_plan(job, args);
  // Under mpirun: this rank's tile of the stock (app/tiled_run.hpp); otherwise the whole stock.
  const removal::Tile tile = process_tile();
  const bool root = mpi_rank() == 0;
  if (args.tiles_out && tile.whole())
    throw core::Error("--tiles-out: writes one file per MPI rank; run under mpirun -np N (N > 1)");
  if (args.tiles_out && job.removal.field == core::RemovalSpec::Field::NBuffer)
    throw core::Error(job.file.string() + ": --tiles-out writes each tile's height grid; [removal] field = \"nbuffer\" "
                      "has none (run without --tiles-out: the needles are gathered)");
  TerminalProgress progress(!args.quiet && root);
  std::set<std::string> chain;

  auto t0 = Clock::now();
  sim::Field field = sim::initial_field(job, progress, chain, tile);
  const double t_stock = seconds_since(t0);
  const sim::Field start = field;  // the stock this job starts from (reference "stock")

  const double feed_scale = args.feed_scale.value_or(1.0);
  sim::Motion motion = sim::simulate_motion(job, feed_scale, job.removal.motion, progress);
  sim::add_contour_error(motion, job);

  t0 = Clock::now();
  const double cpu0 = process_cpu_s();
  progress.stage(job.name + ": material removal");
  const removal::PoseTrack track = sim::track_of(motion, job, job.removal.motion);
  const removal::TrackSweeps ts = sim::sweeps_of(job, track);
  const std::size_t sweeps_in_tile = sim::cut_field(field, ts.sweeps);
  progress.done();
  const double t_cut = seconds_since(t0), cpu_cut = process_cpu_s() - cpu0;

  // The reference surface.
  t0 = Clock::now();
  sim::Reference reference = sim::reference_field(job, start, feed_scale, progress);
  const double t_ref = seconds_since(t0);

  const std::filesystem::path dir = args.out_dir.value_or(std::filesystem::current_path());
  nlohmann::json tiles_json;
  if (!tile.whole()) {
    // Every rank's tile figures to rank 0, then the tiles themselves: gathered into the whole field (rank 0 then
    // writes what a one-process run writes), or written by each rank (--tiles-out).
    TileFigures mine;
    const removal::DexelGrid* g0 = field.grids().empty() ? nullptr : field.grids().front();
    mine.rows = g0 ? g0->nv() : static_cast<double>(field.needles.size());
    mine.rays = static_cast<double>(field.rays());
    mine.sweeps = static_cast<double>(sweeps_in_tile);
    mine.memory_bytes = static_cast<double>(field.memory_bytes() + (reference.field ? reference.field->memory_bytes() : 0));
    mine.removal_s = t_cut;
    mine.removal_cpu_s = cpu_cut;
    std::optional<TileFiles> files;
    if (args.tiles_out) {
      std::error_code ec;
      std::filesystem::create_directories(dir, ec);
      if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
      progress.stage(job.name + ": writing the tiles");
      files = write_tile(dir, job.name, field, reference.field ? &*reference.field : nullptr);
      progress.done();
    }
    mine.peak_rss_bytes = peak_rss_bytes();
    mine.cpu_s = process_cpu_s();
    quiet_barrier();  // ranks that finished early sleep rather than spin in the gathers
    const std::vector<TileFigures> all = gather_tile_figures(mine);
    tiles_json = {{"ranks", tile.count},
                  {"split", "each dexel grid's rows (needles: blocks of 64) in equal bands, one per rank"},
                  {"gathered", !args.tiles_out},
                  {"per_rank", nlohmann::json::array()}};
    for (std::size_t r = 0; r < all.size(); ++r)
      tiles_json["per_rank"].push_back({{"rank", r}, {"rows", all[r].rows}, {"rays", all[r].rays},
                                        {"sweeps", all[r].sweeps}, {"field_memory_bytes", all[r].memory_bytes},
                                        {"peak_rss_bytes", all[r].peak_rss_bytes}, {"removal_s", all[r].removal_s},
                                        {"removal_cpu_s", all[r].removal_cpu_s}, {"cpu_s", all[r].cpu_s}});
    if (args.tiles_out) {
      write_tile_manifest(dir, job.name, field, *files);
      if (root) write_tiles_report(job, args, dir, field, reference, motion, ts, tiles_json, t_start);
      quiet_barrier();
      return 0;
    }
    progress.stage(job.name + ": gathering the tiles to rank 0");
    std::optional<sim::Field> whole = gather_field(field);
    std::optional<sim::Field> whole_ref;
    if (reference.field) whole_ref = gather_field(*reference.field);
    progress.done();
    if (!root) {
      quiet_barrier();  // while rank 0 writes the outputs (an error there aborts every rank)
      return 0;
    }
    field = std::move(*whole);
    if (reference.field) reference.field = std::move(*whole_ref);
  }
  const std::optional<sim::Field>& ref = reference.field;
  const std::string& ref_name = reference.name;

  // Outputs.
  t0 = Clock::now();
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
    const core::HeightGrid pred = sim::surface_of(field);
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
      const core::HeightGrid rs = sim::surface_of(*ref);
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
    const Eigen::VectorXd pred = sim::needle_offsets(field);
    const Eigen::VectorXd rs = ref ? sim::needle_offsets(*ref) : Eigen::VectorXd::Constant(pred.size(), NAN);
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
    images.signals = sim::motion_signals(job, motion.program, motion.interp.setpoints, *motion.response, *motion.contour,
                                    feed_scale);
    sim::write_signals(dir / "signals.csv", *images.signals);
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
                       {"motion", sim::motion_name(job.removal.motion)},
                       {"track_points", ts.points},
                       {"sweeps", ts.sweeps.size()},
                       {"track_tolerance_mm", sim::track_tolerance(job, sim::track_turns(track))},
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
  if (!tiles_json.is_null()) report["tiles"] = tiles_json;
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
    // Follow-up error of every axis (the feed-drive simulation paper section 4 reports the rotary axes' in degrees) and of the tool axis.
    const auto kin = motion::make_kinematics(job.machine);
    report["axis_following_error"] =
        sim::axis_following_json(job.machine, motion.interp.setpoints, motion.response->position, kin.get(),
                            [&](Eigen::Index k) { return sim::tlo_at(motion, k); });
  }
  std::optional<sim::ContourStats> cutting;
  if (motion.contour) {
    cutting = sim::cutting_contour_stats(*motion.contour, motion.interp.setpoints, motion.program);
    report["contour_error"] = sim::contour_json(*motion.contour, *cutting);
  }
  report["files"] = files;
  nlohmann::json timings = motion.timings;
  timings["stock"] = t_stock;
  timings["removal"] = t_cut;
  timings["removal_cpu"] = cpu_cut;  // every thread's CPU time (the machine may be loaded: wall time stretches)
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
                job.name.c_str(), sim::motion_name(job.removal.motion), ts.sweeps.size(), field.part.active_voxels(),
                job.removal.voxel_mm, field.memory_bytes() / 1e6, field.vdb_estimate_bytes / 1e6);
  else
    std::printf("job %s: %s motion, %zu sweeps on %zu rays (%.1f MB)\n", job.name.c_str(),
                sim::motion_name(job.removal.motion), ts.sweeps.size(), field.rays(), field.memory_bytes() / 1e6);
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
  if (!tile.whole()) quiet_barrier();
  return 0;
}

}  // namespace vmsim::app
