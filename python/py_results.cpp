// The results of a job's chain as Python objects: Setpoints (motion::InterpResult), Response (drives::AxisResponse),
// Motion (sim::MotionRun), Result (sim::RunResult). Matrices are numpy views of the Eigen members (column-major:
// Fortran-ordered arrays of shape (samples, axes)); a view keeps its result alive.
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/timing.hpp"
#include "python/py_job.hpp"
#include "render/mesh_io.hpp"
#include "render/report_html.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"
#include "sim/motion_run.hpp"
#include "sim/run.hpp"
#include "sim/run_outputs.hpp"
#include "sim/tools.hpp"

#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

namespace vmsim::python {

namespace fs = std::filesystem;

namespace {

// A run and what job.run(out=...) wrote.
struct PyResult {
  sim::RunResult run;
  nlohmann::json report;  // run.report, with "files" and the write's timings when written
  std::optional<fs::path> out;
  std::vector<std::string> files;
};

constexpr auto kRef = py::return_value_policy::reference_internal;

// t = k Te for each row.
Eigen::ArrayXd times(Eigen::Index n, double period_s) {
  return Eigen::ArrayXd::LinSpaced(n, 0, static_cast<double>(n - 1)) * period_s;
}

}  // namespace

void bind_results(py::module_& m) {
  py::class_<motion::InterpResult, std::shared_ptr<motion::InterpResult>>(m, "Setpoints",
                                                                          R"(The interpolator's output: the
axis commands every period_s (Te).

position: (samples, axes) float64, axis units (mm; rad for rotary axes), column k = axis_names[k] (a Fortran-ordered
view: each axis's samples are contiguous); t_s: sample times (s); path_speed_mm_per_s, path_length_mm: along the
smoothed path; move_index: the program move each sample lies on; cycle_time_s; stats: the interpolator's counts.)")
      .def_property_readonly("period_s", [](const motion::InterpResult& r) { return r.setpoints.period_s; })
      .def_property_readonly("axis_names", [](const motion::InterpResult& r) { return r.setpoints.axis_names; })
      .def_property_readonly(
          "position", [](motion::InterpResult& r) -> Eigen::MatrixXd& { return r.setpoints.position; }, kRef)
      .def_property_readonly(
          "path_speed_mm_per_s",
          [](motion::InterpResult& r) -> Eigen::ArrayXd& { return r.setpoints.path_speed_mm_per_s; }, kRef)
      .def_property_readonly(
          "path_length_mm", [](motion::InterpResult& r) -> Eigen::ArrayXd& { return r.setpoints.path_length_mm; }, kRef)
      .def_property_readonly(
          "move_index", [](motion::InterpResult& r) -> Eigen::ArrayXi& { return r.setpoints.move_index; }, kRef)
      .def_property_readonly(
          "t_s", [](const motion::InterpResult& r) { return times(r.setpoints.samples(), r.setpoints.period_s); })
      .def_property_readonly("samples", [](const motion::InterpResult& r) { return r.setpoints.samples(); })
      .def_property_readonly("cycle_time_s", [](const motion::InterpResult& r) { return r.stats.cycle_time_s; })
      .def_property_readonly("stats",
                             [](const motion::InterpResult& r) {
                               py::dict d;
                               d["cycle_time_s"] = r.stats.cycle_time_s;
                               d["moves"] = r.stats.moves;
                               d["blends"] = r.stats.blends;
                               d["exact_stops"] = r.stats.exact_stops;
                               d["repair_passes"] = r.stats.repair_passes;
                               return d;
                             })
      .def("__len__", [](const motion::InterpResult& r) { return r.setpoints.samples(); })
      .def("__repr__", [](const motion::InterpResult& r) {
        return "<vmsim.Setpoints " + std::to_string(r.setpoints.samples()) + " samples x " +
               std::to_string(r.setpoints.axis_names.size()) + " axes, Te " + std::to_string(r.setpoints.period_s) +
               " s>";
      });

  py::class_<drives::AxisResponse, std::shared_ptr<drives::AxisResponse>>(m, "Response",
                                                                          R"(The drives' actual motion: one row
per setpoint (row k at t = k Te), then the settling rows.

position, velocity, acceleration, jerk: (rows, axes) float64 in axis units (mm, rad) per s, s^2, s^3;
current_A, current_setpoint_A, current_mean_A, current_peak_A: (rows, axes) motor currents (A). Fortran-ordered views.)")
      .def_readonly("period_s", &drives::AxisResponse::period_s)
      .def_readonly("axis_names", &drives::AxisResponse::axis_names)
      .def_property_readonly(
          "position", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.position; }, kRef)
      .def_property_readonly(
          "velocity", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.velocity; }, kRef)
      .def_property_readonly(
          "acceleration", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.acceleration; }, kRef)
      .def_property_readonly(
          "jerk", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.jerk; }, kRef)
      .def_property_readonly(
          "current_A", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.current_A; }, kRef)
      .def_property_readonly(
          "current_setpoint_A", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.current_setpoint_A; }, kRef)
      .def_property_readonly(
          "current_mean_A", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.current_mean_A; }, kRef)
      .def_property_readonly(
          "current_peak_A", [](drives::AxisResponse& r) -> Eigen::MatrixXd& { return r.current_peak_A; }, kRef)
      .def_property_readonly("t_s", [](const drives::AxisResponse& r) { return times(r.samples(), r.period_s); })
      .def("__len__", [](const drives::AxisResponse& r) { return r.samples(); });

  py::class_<sim::MotionRun, std::shared_ptr<sim::MotionRun>>(m, "Motion",
                                                              R"(A job's motion (`vmsim motion`): the program,
the setpoints, the drives' response, and the contour error of the actual tool tip against the commanded path.

contour_error_mm: signed, per response row (positive: outside a curve); contour_foot_segment: the command segment
holding each foot point; report: the figures `vmsim motion` writes to report.json (a dict).)")
      .def_property_readonly(
          "program", [](sim::MotionRun& r) -> core::ToolPath& { return r.program; }, kRef)
      .def_property_readonly(
          "setpoints", [](sim::MotionRun& r) -> motion::InterpResult& { return r.interp; }, kRef)
      .def_property_readonly(
          "response", [](sim::MotionRun& r) -> drives::AxisResponse& { return r.response; }, kRef)
      .def_property_readonly(
          "contour_error_mm", [](sim::MotionRun& r) -> Eigen::ArrayXd& { return r.contour.signed_mm; }, kRef)
      .def_property_readonly(
          "contour_foot_segment", [](sim::MotionRun& r) -> Eigen::ArrayXi& { return r.contour.foot_segment; }, kRef)
      .def_property_readonly("contour_error_max_abs_mm", [](const sim::MotionRun& r) { return r.contour.max_abs_mm; })
      .def_property_readonly("contour_error_rms_mm", [](const sim::MotionRun& r) { return r.contour.rms_mm; })
      .def_property_readonly("contour_error_mse_um2", [](const sim::MotionRun& r) { return r.contour.mse_um2; })
      .def_readonly("setpoint_limits_held", &sim::MotionRun::setpoint_limits_held)
      .def_readonly("currents_within_limit", &sim::MotionRun::currents_within_limit)
      .def_property_readonly("report", [](const sim::MotionRun& r) { return to_python(r.report); });

  py::class_<PyResult, std::shared_ptr<PyResult>>(m, "Result", R"(A whole run (`vmsim run`).

surface, reference, deviation, deviation_vertical: vmsim.Grid (heights on the z-map's nodes, the reference's, and
surface - reference along the reference's normal and vertically: negative is overcut), or None (no reference; N-buffer fields have needles instead: needle_offset_mm,
needle_reference_mm, needle_deviation_mm); marks: a list of dicts as report.json lists them (depth_mm, kind,
x_mm, y_mm, x_extent_mm, y_extent_mm, area_mm2, depth_vertical_mm, slope_deg, steep_wall), deepest first; report: report.json as a dict; mesh: the part as a
vmsim.Mesh with point_data["deviation_mm"], or None; tools: the job's tools as report.json lists them (tool, type,
diameter_mm, ..., last_cut_area_mm2 on a job with several); tool_map: for a job with several tools on a z-map or
tri-dexel field, an int8 array of the surface's shape (ny, nx) giving per node the index into tools of the tool that
last cut it (-1: uncut), what images/tools.png draws; else None; out, files: where job.run(out=...) wrote and what.)")
      .def_property_readonly(
          "surface", [](PyResult& r) -> core::HeightGrid* { return r.run.surface ? &*r.run.surface : nullptr; }, kRef)
      .def_property_readonly(
          "reference",
          [](PyResult& r) -> core::HeightGrid* {
            return r.run.reference_surface ? &*r.run.reference_surface : nullptr;
          },
          kRef)
      .def_property_readonly(
          "deviation", [](PyResult& r) -> core::HeightGrid* { return r.run.deviation ? &*r.run.deviation : nullptr; },
          kRef)
      .def_property_readonly(
          "deviation_vertical",
          [](PyResult& r) -> core::HeightGrid* {
            return r.run.deviation_vertical ? &*r.run.deviation_vertical : nullptr;
          },
          kRef)
      .def_property_readonly(
          "mesh",
          [](PyResult& r) -> core::TriangleMesh* {
            if (r.run.part_mesh_triangles >= 0 && !r.run.part_mesh) r.run.part_mesh = sim::grid_part_mesh(r.run);
            if (r.run.part_mesh) return &*r.run.part_mesh;
            if (r.run.level_set) return &r.run.level_set->mesh;
            return nullptr;
          },
          kRef)
      .def_property_readonly(
          "needle_offset_mm", [](PyResult& r) -> Eigen::VectorXd& { return r.run.needle_offset_mm; }, kRef)
      .def_property_readonly(
          "needle_reference_mm", [](PyResult& r) -> Eigen::VectorXd& { return r.run.needle_reference_mm; }, kRef)
      .def_property_readonly(
          "needle_deviation_mm", [](PyResult& r) -> Eigen::VectorXd& { return r.run.needle_deviation_mm; }, kRef)
      .def_property_readonly(
          "marks", [](const PyResult& r) { return to_python(r.report.value("marks", nlohmann::json::array())); })
      .def_property_readonly("report", [](const PyResult& r) { return to_python(r.report); })
      .def_property_readonly("reference_name", [](const PyResult& r) { return r.run.cut.reference.name; })
      // What images/tools.png draws (issue 24 section 1), as data: a new int8 array in the surface's layout.
      .def_property_readonly("tool_map",
                             [](const PyResult& r) -> py::object {
                               const auto& m = r.run.cut.tool_map;
                               if (!m) return py::none();
                               const metrology::IndexGrid index = sim::tool_index(*m);
                               py::array_t<std::int8_t> a({index.rows(), index.cols()});
                               std::copy(index.data(), index.data() + index.size(), a.mutable_data());
                               return a;
                             })
      .def_property_readonly(
          "tools",
          [](const PyResult& r) { return to_python(r.report.value("tools", nlohmann::json::object()).value("list", nlohmann::json::array())); })
      .def_readonly("out", &PyResult::out)
      .def_readonly("files", &PyResult::files)
      .def("__repr__", [](const PyResult& r) {
        return "<vmsim.Result " + r.report.value("job", std::string()) + ": " +
               std::to_string(r.report["marks"].size()) + " marks>";
      });
}

py::object interpolate_job(const PyJob& pj, py::object progress) {
  const std::shared_ptr<const LoadedJob> loaded = pj.loaded();
  const double feed_scale = pj.feed_scale();
  auto r = call_released(progress, [&](core::Progress& p) {
    sim::ChainOptions o;
    o.feed_scale = feed_scale;
    const sim::Chain chain(loaded->job, o);
    const core::ToolPath program = sim::read_job_program(loaded->job);
    p.stage(loaded->job.name + ": interpolation");
    auto out = std::make_shared<motion::InterpResult>(chain.interpolate(program));
    p.done();
    return out;
  });
  return py::cast(r);
}

py::object simulate_job(const PyJob& pj, bool full_rate_trace, py::object progress) {
  const std::shared_ptr<const LoadedJob> loaded = pj.loaded();
  sim::MotionRunOptions o;
  o.feed_scale = pj.feed_scale();
  o.full_rate_trace = full_rate_trace;
  auto r = call_released(progress, [&](core::Progress& p) {
    return std::make_shared<sim::MotionRun>(sim::run_motion(loaded->job, o, p));
  });
  return py::cast(r);
}

py::object run_job(const PyJob& pj, std::optional<fs::path> out, bool render, py::object progress) {
  if (render) {
    PyErr_SetString(PyExc_NotImplementedError,
                    "job.run(render=True): the pictures are drawn by the command line only (app/result_images); run "
                    "`vmsim render DIR` on the directory job.run(out=DIR) wrote");
    throw py::error_already_set();
  }
  const std::shared_ptr<const LoadedJob> loaded = pj.loaded();
  sim::RunOptions o;
  o.feed_scale = pj.feed_scale();
  auto res = std::make_shared<PyResult>();
  call_released(progress, [&](core::Progress& p) {
    const auto t_start = core::Clock::now();
    const core::Job& job = loaded->job;
    // As `vmsim run`: OUT locked before the run, written in staging, swapped into place whole at the end
    // (core/output_dir.hpp); an interrupted or failed call leaves the previous result. SIGINT stays Python's.
    std::optional<core::OutputDir> dir;
    if (out) dir.emplace(*out, "vmsim run (Python)", core::OutputDir::Signals::Leave);
    res->run = sim::run_job(job, o, p);
    res->report = res->run.report;
    if (!dir) return 0;
    // The files `vmsim run --no-render` writes, through its writer, then its report.json (and report.html).
    const auto t0 = core::Clock::now();
    nlohmann::json outputs;
    res->files = sim::write_run_outputs(job, res->run, dir->path(), render::write_vtp, &outputs);
    res->report["outputs"] = outputs["outputs"];
    res->report["files"] = res->files;
    res->report["timings_s"]["write"] = core::seconds_since(t0);
    res->report["timings_s"]["total"] = core::seconds_since(t_start);
    render::write_report(dir->path() / "report.json", res->report);
    res->files.push_back("report.json");
    dir->commit();
    res->out = *out;
    return 0;
  });
  return py::cast(res);
}

}  // namespace vmsim::python
