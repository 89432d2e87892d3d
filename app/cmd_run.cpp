// vmsim run JOB: the whole chain (sim/run.hpp). Program -> interpolator -> drives -> kinematics -> material removal
// -> surfaces, and the marks: the signed deviation of the predicted surface from the reference surface. This file
// parses nothing and computes nothing: it runs the chain (tiled under MPI), writes the results, the pictures and
// report.json, and prints the summary.
#include "app/commands.hpp"
#include "app/mpi_session.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "app/result_images.hpp"
#include "app/run_plan.hpp"
#include "app/tiled_run.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/stl.hpp"
#include "core/timing.hpp"
#include "core/units.hpp"
#include "render/mesh_io.hpp"
#include "sim/contour_stats.hpp"
#include "sim/job_program.hpp"
#include "sim/run.hpp"
#include "sim/run_outputs.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <optional>

namespace vmsim::app {

namespace {

using core::Clock;
using core::seconds_since;
namespace fs = std::filesystem;

// --tiles-out, rank 0: report.json without the whole-part results (marks, meshes, pictures need the whole grid):
// the motion's figures, the removal's, and every rank's tile.
void write_tiles_report(const core::Job& job, const fs::path& dir, const fs::path& shown, const sim::Cut& cut,
                        const nlohmann::json& tiles_json, Clock::time_point t_start) {
  nlohmann::json report = report_header("run", job);
  double rays = 0;
  for (const auto& r : tiles_json["per_rank"]) rays += r["rays"].get<double>();
  report["removal"] = {{"method", "dexel"},
                       {"field", cut.field.kind == core::RemovalSpec::Field::ZMap ? "zmap" : "tridexel"},
                       {"spacing_mm", cut.field.spacing_mm},
                       {"rays", rays},
                       {"motion", sim::motion_name(job.removal.motion)},
                       {"sweeps", cut.sweeps.sweeps.size()},
                       {"track_tolerance_mm", job.removal.track_tolerance_mm},
                       {"track_error_bound_mm", cut.sweeps.error_bound_mm}};
  report["tiles"] = tiles_json;
  report["tiles"]["manifest"] = "tiles.json";
  report["reference"] = cut.reference.name;
  const sim::Motion& motion = cut.motion;
  if (motion.contour) {
    const sim::ContourStats cutting =
        sim::cutting_contour_stats(*motion.contour, motion.interp.setpoints, motion.program);
    report["contour_error"] = sim::contour_json(*motion.contour, cutting);
  }
  if (job.removal.motion != core::RemovalSpec::Motion::Program)
    report["interpolation"] = {{"cycle_time_s", motion.interp.stats.cycle_time_s},
                               {"setpoints", motion.interp.setpoints.samples()},
                               {"period_s", motion.interp.setpoints.period_s}};
  if (motion.response) report["drive_checks"] = motion.drive_checks.axes;
  sim::add_verdict(report, motion.drive_checks.warnings);
  report["files"] = {"tiles.json", "report.json"};
  report["timings_s"] = {{"total", seconds_since(t_start)}};
  write_report(dir / "report.json", report);
  std::printf("job %s: %s motion, %zu sweeps on %.0f rays in %d tiles\n", job.name.c_str(),
              sim::motion_name(job.removal.motion), cut.sweeps.sweeps.size(), rays, tiles_json["ranks"].get<int>());
  std::printf("wrote %s: tiles.json, report.json and tiles/ (one X3P per rank%s) in %.1f s\n", shown.string().c_str(),
              cut.reference.field ? ", surface and deviation" : "", seconds_since(t_start));
}

// A tiled run (under mpirun): every rank's figures to rank 0, then the tiles themselves, gathered into the whole
// field (rank 0 then holds what a one-process run holds) or written by each rank (--tiles-out). Returns whether
// this process goes on to write the outputs (rank 0 of a gathered run).
bool gather_tiles(const core::Job& job, const RunArgs& args, const fs::path& dir, const fs::path& shown, sim::Cut& cut,
                  nlohmann::json& tiles_json, TerminalProgress& progress, Clock::time_point t_start) {
  const removal::Tile& tile = cut.field.tile;
  const bool root = mpi_rank() == 0;
  TileFigures mine;
  const removal::DexelGrid* g0 = cut.field.grids().empty() ? nullptr : cut.field.grids().front();
  mine.rows = g0 ? g0->nv() : static_cast<double>(cut.field.needles.size());
  mine.rays = static_cast<double>(cut.field.rays());
  mine.sweeps = static_cast<double>(cut.sweeps_in_tile);
  mine.memory_bytes =
      static_cast<double>(cut.field.memory_bytes() + (cut.reference.field ? cut.reference.field->memory_bytes() : 0));
  mine.removal_s = cut.timings["removal"].get<double>();
  mine.removal_cpu_s = cut.timings["removal_cpu"].get<double>();
  std::optional<TileFiles> files;
  if (args.tiles_out) {
    core::create_result_subdir(dir);  // rank 0's staging directory, seen by every rank (one file system)
    progress.stage(job.name + ": writing the tiles");
    files = write_tile(dir, job.name, cut.field, cut.reference.field ? &*cut.reference.field : nullptr);
    progress.done();
  }
  mine.peak_rss_bytes = peak_rss_bytes();
  mine.cpu_s = process_cpu_s();
  quiet_barrier("the gathering of the tiles (after the cut)");  // ranks that finished early sleep, not spin
  const std::vector<TileFigures> all = gather_tile_figures(mine);
  tiles_json = {{"ranks", tile.count},
                {"split", "each dexel grid's rows (needles: blocks of 64) in equal bands, one per rank"},
                {"gathered", !args.tiles_out},
                {"per_rank", nlohmann::json::array()}};
  for (std::size_t r = 0; r < all.size(); ++r)
    tiles_json["per_rank"].push_back({{"rank", r},
                                      {"rows", all[r].rows},
                                      {"rays", all[r].rays},
                                      {"sweeps", all[r].sweeps},
                                      {"field_memory_bytes", all[r].memory_bytes},
                                      {"peak_rss_bytes", all[r].peak_rss_bytes},
                                      {"removal_s", all[r].removal_s},
                                      {"removal_cpu_s", all[r].removal_cpu_s},
                                      {"cpu_s", all[r].cpu_s}});
  if (args.tiles_out) {
    write_tile_manifest(dir, job.name, cut.field, *files);
    if (root) write_tiles_report(job, dir, shown, cut, tiles_json, t_start);
    quiet_barrier();
    return false;
  }
  progress.stage(job.name + ": gathering the tiles to rank 0");
  std::optional<sim::Field> whole = gather_field(cut.field);
  std::optional<sim::Field> whole_ref;
  if (cut.reference.field) whole_ref = gather_field(*cut.reference.field);
  progress.done();
  if (!root) {
    quiet_barrier("the end of the run (rank 0 writes the outputs)");  // an error there aborts every rank
    return false;
  }
  cut.field = std::move(*whole);
  if (cut.reference.field) cut.reference.field = std::move(*whole_ref);
  return true;
}

// The result lines (the field, the contour error, the marks), printed before the pictures are drawn: they are what
// the user waits for (the demo's mark table), and the pictures add nothing to them.
void print_results(const core::Job& job, const sim::RunResult& r) {
  const sim::Cut& c = r.cut;
  if (c.field.vdb)
    std::printf("job %s: %s motion, %zu sweeps on a level set of %zu voxels at %g mm (%.1f MB, estimated %.1f MB)\n",
                job.name.c_str(), sim::motion_name(job.removal.motion), c.sweeps.sweeps.size(),
                c.field.part.active_voxels(), job.removal.voxel_mm, c.field.memory_bytes() / 1e6,
                c.field.vdb_estimate_bytes / 1e6);
  else
    std::printf("job %s: %s motion, %zu sweeps on %zu rays (%.1f MB)\n", job.name.c_str(),
                sim::motion_name(job.removal.motion), c.sweeps.sweeps.size(), c.field.rays(),
                c.field.memory_bytes() / 1e6);
  if (r.report.contains("contour_error")) {
    const nlohmann::json& cut = r.report["contour_error"]["cutting_moves"];
    std::printf("contour error on cutting moves: max %.2f um, rms %.2f um\n", cut["max_abs_mm"].get<double>() * 1e3,
                cut["rms_mm"].get<double>() * 1e3);
  }
  std::printf("reference: %s\n", c.reference.name.c_str());
  if (c.reference.field && r.marks.empty()) std::printf("marks: none deeper than 1 um\n");
  for (std::size_t k = 0; k < r.marks.size() && k < 5; ++k) {
    const metrology::Mark& m = r.marks[k];
    // The depth is along the reference's normal; on a slope the vertical figure (what a height map shows) beside it.
    const std::string vertical =
        std::isfinite(m.depth_vertical_mm) && std::abs(m.depth_vertical_mm - m.depth_mm) > 5e-6
            ? fmt::format(" along the normal ({:.2f} um vertically, on a {:.0f} deg slope{})",
                          m.depth_vertical_mm * 1e3, m.slope_rad * 180.0 / core::units::kPi, m.steep_wall ? ", a steep wall" : "")
            : "";
    std::printf("mark %zu: %s %.2f um%s at x %.3f y %.3f, %.3f x %.3f mm\n", k + 1, m.overcut ? "overcut " : "undercut",
                m.depth_mm * 1e3, vertical.c_str(), m.x_mm, m.y_mm, m.x_extent_mm, m.y_extent_mm);
  }
  std::fflush(stdout);
}

void print_written(const fs::path& dir, std::size_t n_files, std::size_t n_images, Clock::time_point t_start) {
  if (n_images > 0) std::printf("images: %s (%zu PNG files)\n", (dir / "images").string().c_str(), n_images);
  std::printf("wrote %s (%zu files) in %.1f s\n", dir.string().c_str(), n_files, seconds_since(t_start));
}

// The pictures' failure of any kind (bad_alloc at a large --image-size included) as a message: the results and
// report.json are written whatever the pictures do. The result is written and printed by now: what the pictures draw
// is moved out of it and the rest (motion, track, sweeps, field, meshes: ~0.3 GB on flower_mold at 0.1 mm) is freed
// first, since the drawing is otherwise the run's peak (issue 21). `report` is the result's report, moved out before.
std::optional<std::string> draw_pictures(const core::Job& job, sim::RunResult&& result, const nlohmann::json& report,
                                         const fs::path& dir, const ImageOptions& image_opt,
                                         std::vector<std::string>& files, std::size_t& n_images) {
  ResultData images;
  images.job = job.name;
  images.reference = result.cut.reference.name;
  images.marks = std::move(result.marks);
  images.surface = std::move(result.surface);
  images.deviation = std::move(result.deviation);
  images.signals = std::move(result.signals);
  std::optional<sim::ToolMap> tool_map = std::move(result.cut.tool_map);
  result = sim::RunResult{};
  if (const auto& m = tool_map; m && images.surface && images.surface->nx() == m->nu && images.surface->ny() == m->nv) {
    images.tool_index = sim::tool_index(*m).cast<int>();
    // The legend from report.json's tools: "T1 flat D6.35" (their areas are in report.json and report.html).
    for (const nlohmann::json& t : report["tools"]["list"])
      images.tool_names.push_back(tool_legend(t));
  }
  try {
    // Test hook (tests/app/outdir_cli_test.cpp, README "What you can rely on"): the pictures run out of memory.
    if (const char* h = std::getenv("VMSIM_TEST_PICTURES_THROW"); h && std::string(h) == "bad_alloc")
      throw std::bad_alloc();
    for (const std::string& f : write_result_images(images, dir / "images", image_opt)) {
      files.push_back("images/" + f);
      ++n_images;
    }
  } catch (const core::Error& e) {
    return e.what();
  } catch (const std::bad_alloc&) {
    return "out of memory while drawing (a smaller --image-size needs less)";
  } catch (const std::exception& e) {
    return std::string("internal error while drawing: ") + e.what();
  } catch (...) {
    return "internal error while drawing";
  }
  return std::nullopt;
}

}  // namespace

int run_run(const RunArgs& args) {
  const auto t_start = Clock::now();
  core::Job job = core::load_job(args.job);
  // Test hook (tests/app/study_cli_test.cpp, README "What you can rely on"): a crash in the run of this job.
  if (const char* h = std::getenv("VMSIM_TEST_SEGFAULT_JOB"); h && job.name == h) std::raise(SIGSEGV);
  // A CL program's own tool when the job gives none (APT TLDATA/, CUTTER/); a note when the job's differs from it.
  if (const auto note = sim::use_program_tool(job); note && mpi_rank() == 0)
    std::fprintf(stderr, "tool: %s\n", note->c_str());
  // The picture options are checked now, not after the simulation.
  ImageArgs image_args;
  image_args.size = args.image_size;
  const ImageOptions image_opt = args.no_render ? ImageOptions{} : image_options(image_args);
  if (args.plan) return run_plan(job, args);
  // Under mpirun: this rank's tile of the stock (app/tiled_run.hpp); otherwise the whole stock.
  sim::RunOptions options;
  options.feed_scale = args.feed_scale.value_or(1.0);
  options.tile = process_tile();
  if (args.tiles_out && options.tile.whole())
    throw core::Error("--tiles-out: writes one file per MPI rank; run under mpirun -np N (N > 1)");
  if (args.tiles_out && job.removal.field == core::RemovalSpec::Field::NBuffer)
    throw core::Error(job.file.string() +
                      ": --tiles-out writes each tile's height grid; [removal] field = \"nbuffer\" "
                      "has none (run without --tiles-out: the needles are gathered)");
  TerminalProgress progress(!args.quiet && mpi_rank() == 0);
  // Rank 0 owns the output directory (core/output_dir.hpp): locked now, before the run; written in its staging
  // directory; swapped into place whole at the end. With --tiles-out every rank writes its tile there.
  std::optional<core::OutputDir> out;
  fs::path dir = out_dir_or_default(args.out_dir, job.name, "run");
  const fs::path shown = dir;
  if (mpi_rank() == 0) {
    out.emplace(dir, "vmsim run");
    dir = out->path();
  }
  if (args.tiles_out) dir = mpi_broadcast(dir.string());

  sim::Cut cut = sim::cut_job(job, options, progress);
  // What the program reader accepted without modelling it (units not given, tool changes, --lenient statements).
  const std::vector<std::string> program_warnings = cut.motion.program.warnings;
  if (mpi_rank() == 0)
    for (const std::string& w : program_warnings) std::fprintf(stderr, "vmsim: warning: %s\n", w.c_str());
  nlohmann::json tiles_json;
  if (!options.tile.whole() && !gather_tiles(job, args, dir, shown, cut, tiles_json, progress, t_start)) {
    if (out) out->commit();  // --tiles-out: every rank's tile is written (gather_tiles ends in a barrier)
    return 0;
  }
  sim::RunResult result = sim::finish_run(job, std::move(cut), progress);

  auto t0 = Clock::now();
  const double cpu0 = core::process_cpu_s();
  nlohmann::json outputs;
  std::vector<std::string> files = sim::write_run_outputs(job, result, dir, render::write_vtp, &outputs);
  const double t_write = seconds_since(t0), cpu_write = core::process_cpu_s() - cpu0;
  if (mpi_rank() == 0)
    for (const auto& n : outputs["outputs"].value("notes", nlohmann::json::array()))
      std::fprintf(stderr, "vmsim: note: %s\n", n.get<std::string>().c_str());
  print_results(job, result);
  nlohmann::json report = std::move(result.report);

  // Pictures, after every result file: a failure to draw loses no result.
  std::optional<std::string> render_error;
  std::size_t n_images = 0;
  double t_render = 0, cpu_render = 0;
  if (!args.no_render) {
    t0 = Clock::now();
    const double cpu1 = core::process_cpu_s();
    progress.stage(job.name + ": pictures");
    render_error = draw_pictures(job, std::move(result), report, dir, image_opt, files, n_images);
    progress.done();
    t_render = seconds_since(t0), cpu_render = core::process_cpu_s() - cpu1;
  }

  report["outputs"] = outputs["outputs"];
  if (!program_warnings.empty()) report["program_warnings"] = program_warnings;
  if (!tiles_json.is_null()) report["tiles"] = tiles_json;
  report["files"] = files;
  report["timings_s"]["write"] = t_write;
  report["timings_s"]["write_cpu"] = cpu_write;  // every thread's CPU time (llvmpipe draws in its own)
  if (!args.no_render) report["timings_s"]["render"] = t_render, report["timings_s"]["render_cpu"] = cpu_render;
  if (render_error) report["render_error"] = *render_error;
  report["timings_s"]["total"] = seconds_since(t_start);
  write_report(dir / "report.json", report);
  files.push_back("report.json");
  if (out) out->commit();

  print_written(shown, files.size(), n_images, t_start);
  const int verdict_code = print_verdict(report);
  if (render_error)
    throw core::Error("the results are written to " + shown.string() +
                      ", but the pictures could not be drawn "
                      "(--no-render skips them): " +
                      *render_error);
  if (!options.tile.whole()) quiet_barrier();
  return verdict_code;
}

}  // namespace vmsim::app
