// The papers' methods on a job, as the commands run them (sim/oga, sim/plan_feed, sim/compensate): each returns its
// report.json figures as a dict and its main results as arrays. Defaults are the commands' defaults.
#include "core/error.hpp"
#include "python/py_job.hpp"
#include "sim/compensate.hpp"
#include "sim/oga.hpp"
#include "sim/plan_feed.hpp"
#include "sim/report.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>

namespace vmsim::python {

namespace {

// MIN, MIN + STEP, ... up to MAX, as `vmsim oga --kp-grid MIN:STEP:MAX` expands it (app/cmd_oga.cpp parse_grid).
std::vector<double> grid_of(const std::vector<double>& g, const char* what) {
  if (g.size() == 1 && std::isfinite(g[0])) return g;
  if (g.size() != 3 || !std::isfinite(g[0]) || !std::isfinite(g[2]) || !(g[1] > 0) || !(g[2] >= g[0]))
    throw core::Error(std::string(what) + ": expected (MIN, STEP, MAX) with STEP > 0 and MAX >= MIN, e.g. (1, 0.5, 9)");
  const double n = std::floor((g[2] - g[0]) / g[1] + 1e-9);
  if (n > 10000) throw core::Error(std::string(what) + ": more than 10000 values");
  std::vector<double> out;
  for (int i = 0; i <= static_cast<int>(n); ++i) out.push_back(g[0] + i * g[1]);
  return out;
}

py::dict table_dict(const methods::GainTable& t) {
  py::dict d;
  d["axis_names"] = t.axis_names;
  d["kv_1000_per_min"] = t.kv_1000_per_min;
  d["kf"] = t.kf;
  return d;
}

// report.json as the command writes it, but the files, pictures and write times: its header (inputs and their
// hashes), the method's figures, the method's timings.
py::object report_of(const std::string& command, const core::Job& job, const nlohmann::json& figures,
                     const nlohmann::json& timings, const std::optional<std::filesystem::path>& axis_models = {}) {
  nlohmann::json report = sim::report_header(command, job);
  if (axis_models) report["inputs"]["axis_models"] = {{"path", axis_models->string()}};
  report.update(figures);
  report["timings_s"] = timings;
  return to_python(report);
}

}  // namespace

void bind_methods(py::module_& m) {
  m.def(
      "oga",
      [](const PyJob& pj, std::vector<double> kp_grid, std::vector<double> kf_grid, double gain_step,
         double frequency_hz, const std::string& reference, std::optional<std::pair<double, double>> kp_range,
         bool verify, py::object progress) {
        if (pj.feed_scale() != 1.0) throw core::Error("oga: the job's feed_scale override applies to vmsim run and motion; OGA adjusts the gains for the program's own feeds");
        sim::OgaJobOptions o;
        o.search.kp_grid = grid_of(kp_grid, "kp_grid");
        o.search.kf_grid = grid_of(kf_grid, "kf_grid");
        if (!(gain_step > 0)) throw core::Error("gain_step: expected a gain step > 0 in (m/min)/mm");
        o.search.gain_step = gain_step;
        if (!(frequency_hz > 0)) throw core::Error("frequency_hz: expected a frequency > 0");
        o.search.frequency_hz = frequency_hz;
        if (reference == "best") o.search.reference = methods::OgaOptions::Reference::Best;
        else if (reference == "machine") o.search.reference = methods::OgaOptions::Reference::Machine;
        else throw core::Error("reference \"" + reference + "\": expected best or machine");
        o.range_all = kp_range;
        o.verify = verify;
        const auto loaded = pj.loaded();
        auto r = call_released(progress, [&](core::Progress& p) {
          return std::make_shared<sim::OgaJobResult>(sim::oga_job(loaded->job, o, p));
        });
        py::dict d;
        d["report"] = report_of("oga", loaded->job, r->report, r->timings);
        d["c2"] = table_dict(r->result.table);  // the gain schedule, one row per setpoint
        d["c1"] = table_dict(r->result.c1_table);
        d["c1_mse_um2"] = r->result.c1_mse_um2;
        d["c2_mse_um2"] = r->result.c2_mse_um2;
        d["change_percent"] = r->change_percent;
        d["setpoints"] = py::cast(std::make_shared<motion::InterpResult>(r->interp));
        return d;
      },
      py::arg("job"), py::arg("kp_grid") = std::vector<double>{1, 0.5, 9}, py::arg("kf_grid") = std::vector<double>{0, 0.1, 1.2},
      py::arg("gain_step") = 0.03, py::arg("frequency_hz") = 10.0, py::arg("reference") = "best",
      py::arg("kp_range") = py::none(), py::arg("verify") = true, py::arg("progress") = py::none(),
      R"(Offline gain adjustment (Duong et al.) on a job's biaxial profile, as `vmsim oga` runs it with the same
options: kp_grid, kf_grid as (MIN, STEP, MAX) in (m/min)/mm, gain_step dK, frequency_hz f, reference "best" | "machine"
(C1), kp_range (MIN, MAX) for every adjusted axis. Returns a dict: report (report.json's figures), c2 and c1
(axis_names, kv_1000_per_min and kf per setpoint row), c1_mse_um2, c2_mse_um2, change_percent, setpoints.)");

  m.def(
      "plan_feed",
      [](const PyJob& pj, py::object progress) {
        const auto loaded = pj.loaded();
        auto r = call_released(progress, [&](core::Progress& p) {
          return std::make_shared<sim::PlanFeedResult>(sim::plan_feed(loaded->job, p));
        });
        py::dict d;
        d["report"] = report_of("plan-feed", loaded->job, r->report, r->timings);
        d["ceiling_s_mm"] = py::array_t<double>(static_cast<py::ssize_t>(r->ceiling.s_mm.size()), r->ceiling.s_mm.data());
        d["ceiling_feed_mm_per_s"] =
            py::array_t<double>(static_cast<py::ssize_t>(r->ceiling.feed_mm_per_s.size()), r->ceiling.feed_mm_per_s.data());
        d["model_peak_mm"] = r->model_peak_mm;
        d["model_peak_free_mm"] = r->model_peak_free_mm;
        return d;
      },
      py::arg("job"), py::arg("progress") = py::none(),
      R"(Chen, Ren & Sun's contour-error-constrained feed plan for a job with [feedplan], as `vmsim plan-feed` runs it.
Returns a dict: report (report.json's figures), ceiling_s_mm and ceiling_feed_mm_per_s (the verified plan as the
interpolator's feed ceiling along the path's arc length), model_peak_mm, model_peak_free_mm (eq. 7's estimates).)");

  m.def(
      "compensate",
      [](const PyJob& pj, std::optional<std::filesystem::path> axis_models, int buffer_samples, int max_iterations,
         double smoothing_samples, bool tip_only, py::object progress) {
        sim::CompensateJobOptions o;
        o.axis_models_file = axis_models;
        o.method.buffer_samples = buffer_samples;
        o.method.max_iterations = max_iterations;
        o.method.smoothing_samples = smoothing_samples;
        o.method.orientation = !tip_only;
        const auto loaded = pj.loaded();
        auto r = call_released(progress, [&](core::Progress& p) {
          return std::make_shared<sim::CompensateJobResult>(sim::compensate_job(loaded->job, o, p));
        });
        py::dict d;
        d["report"] = report_of("compensate", loaded->job, r->report, r->timings,
                                axis_models ? axis_models : loaded->job.axis_models_file);
        d["setpoints"] = r->compensation.setpoints;  // compensated axis setpoints, samples x axes
        d["axis_names"] = r->interp.setpoints.axis_names;
        d["original_setpoints"] = py::cast(std::make_shared<motion::InterpResult>(r->interp));
        d["program_text"] = r->compensated_program.text;
        d["program_extension"] = r->compensated_program.extension;
        d["predicted_before_max_mm"] = r->predicted_before.max_mm;
        d["predicted_after_max_mm"] = r->predicted_after.max_mm;
        return d;
      },
      py::arg("job"), py::arg("axis_models") = py::none(), py::arg("buffer_samples") = 0, py::arg("max_iterations") = 6,
      py::arg("smoothing_samples") = 4.0, py::arg("tip_only") = false, py::arg("progress") = py::none(),
      R"(The predictive-compensation paper's contour-error compensation of a job, as `vmsim compensate` runs it.
Returns a dict: report (report.json's figures), setpoints (compensated, samples x axes), axis_names,
original_setpoints, program_text (the compensated program), predicted_before_max_mm, predicted_after_max_mm.)");
}

}  // namespace vmsim::python
