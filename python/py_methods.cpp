// The papers' methods on a job, as the commands run them (sim/oga, sim/plan_feed, sim/compensate): each returns its
// report.json figures as a dict and its main results as arrays. Defaults are the commands' defaults.
#include "core/error.hpp"
#include "python/py_job.hpp"
#include "sim/compensate.hpp"
#include "sim/oga.hpp"
#include "sim/plan_feed.hpp"
#include "sim/report.hpp"
#include "sysid/identify_axes.hpp"
#include "sysid/position_trace.hpp"

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

// One axis's models as `vmsim identify` reports them (app/cmd_identify.cpp): rotary axes' errors in degrees.
py::dict identified_axis(const sysid::AxisIdentification& a) {
  const double f2 = a.rotary ? std::pow(180.0 / 3.14159265358979323846, 2) : 1.0;
  py::dict d, models;
  d["unit"] = a.rotary ? "deg" : "mm";
  py::dict orders;
  orders["na"] = a.orders.na, orders["nb"] = a.orders.nb, orders["nc"] = a.orders.nc, orders["nk"] = a.orders.nk;
  d["orders"] = orders;
  for (const sysid::ModelResult& r : a.models) {
    const sysid::IdentifiedModel& m = r.model;
    py::dict jm;
    jm["rank"] = r.rank;
    jm["b"] = Eigen::VectorXd(m.g.b);
    jm["a"] = Eigen::VectorXd(m.g.a);
    jm["c"] = Eigen::VectorXd(m.c);
    jm["nk"] = m.g.nk;
    jm["static_gain"] = m.g.static_gain();
    jm["estimation_loss"] = m.loss * f2;
    jm["converged"] = m.converged;
    jm["fit_percent"] = r.validation.fit_percent;
    jm["tracking_fit_percent"] = r.validation.tracking_fit_percent;
    jm["r2"] = r.validation.r2;
    jm["mse"] = r.validation.mse * f2;
    jm["max_abs_error"] = r.validation.max_abs_error * std::sqrt(f2);
    jm["white"] = r.validation.white;
    models[sysid::structure_name(m.structure)] = jm;
  }
  d["models"] = models;
  d["chosen"] = sysid::structure_name(a.models[a.chosen].model.structure);
  return d;
}

}  // namespace

void bind_methods(py::module_& m) {
  m.def(
      "identify",
      [](std::vector<std::filesystem::path> traces, std::optional<std::filesystem::path> validate,
         std::vector<std::string> structures, std::pair<int, int> orders_nb_na, int nc, std::optional<int> delay,
         const std::string& use, std::vector<std::string> axes, std::optional<std::filesystem::path> save_to) {
        sysid::AxesIdentificationOptions o;
        o.structures.clear();
        for (const std::string& s : structures) {
          const auto st = sysid::parse_structure(s);
          if (!st) throw core::Error("structures: '" + s + "': expected arx, armax or oe");
          o.structures.push_back(*st);
        }
        if (use != "best") {
          o.use = sysid::parse_structure(use);
          if (!o.use || std::find(o.structures.begin(), o.structures.end(), *o.use) == o.structures.end())
            throw core::Error("use '" + use + "': expected best or one of the structures identified");
        }
        if (nc < 0 || nc > 30) throw core::Error("nc: expected 0 to 30");
        o.nc = nc;
        o.orders = sysid::ModelOrders{orders_nb_na.second, orders_nb_na.first, nc, 1};
        o.delay = delay;
        o.axes = axes;
        if (traces.empty()) throw core::Error("identify: at least one position trace is needed");
        py::dict out;
        std::vector<sysid::AxisIdentification> ids;
        sysid::IdentificationData data;
        {
          py::gil_scoped_release release;
          std::vector<sysid::PositionTrace> tr;
          for (const auto& p : traces) tr.push_back(sysid::read_position_trace_csv(p));
          std::optional<sysid::PositionTrace> vtrace;
          if (validate) vtrace = sysid::read_position_trace_csv(*validate);
          data = sysid::prepare_identification(tr, vtrace ? &*vtrace : nullptr, o);
          for (const sysid::AxisData& a : data.axes) ids.push_back(sysid::identify_axis(a, data.source, o));
          if (save_to)
            sysid::save_axis_models(*save_to, sysid::axis_model_file(data, ids),
                                    {"Written by vmsim.identify (Python)"});
        }
        for (const auto& a : ids) out[py::str(a.name)] = identified_axis(a);
        return out;
      },
      py::arg("traces"), py::arg("validate") = py::none(),
      py::arg("structures") = std::vector<std::string>{"arx", "armax", "oe"},
      py::arg("orders_nb_na") = std::pair<int, int>{2, 5}, py::arg("nc") = 2, py::arg("delay") = py::none(),
      py::arg("use") = "best", py::arg("axes") = std::vector<std::string>{}, py::arg("save_to") = py::none(),
      R"(Each axis of position traces (CSV, as `vmsim motion` writes trace.csv or an NC's trace) identified as a
discrete transfer function from command to encoder position (the predictive-compensation paper), as `vmsim identify`
does: ARX, ARMAX, OE with orders (nb, na), ARMAX noise order nc, delay nk (None: the best ARX loss over 1..5), ranked
by the validation MSE. Returns {axis: {unit, orders, chosen, models: {structure: {rank, b, a, c, nk, fit_percent,
tracking_fit_percent, r2, mse, ...}}}}; save_to writes the axis-model file ([job] axis_models).)");

  m.def(
      "oga",
      [](const PyJob& pj, std::vector<double> kp_grid, std::vector<double> kf_grid, double gain_step,
         double frequency_hz, const std::string& reference, std::optional<std::pair<double, double>> kp_range,
         bool verify, py::object progress) {
        if (pj.feed_scale() != 1.0)
          throw core::Error(
              "oga: the job's feed_scale override applies to vmsim run and motion; OGA adjusts the gains for the "
              "program's own feeds");
        sim::OgaJobOptions o;
        o.search.kp_grid = grid_of(kp_grid, "kp_grid");
        o.search.kf_grid = grid_of(kf_grid, "kf_grid");
        if (!(gain_step > 0)) throw core::Error("gain_step: expected a gain step > 0 in (m/min)/mm");
        o.search.gain_step = gain_step;
        if (!(frequency_hz > 0)) throw core::Error("frequency_hz: expected a frequency > 0");
        o.search.frequency_hz = frequency_hz;
        if (reference == "best")
          o.search.reference = methods::OgaOptions::Reference::Best;
        else if (reference == "machine")
          o.search.reference = methods::OgaOptions::Reference::Machine;
        else
          throw core::Error("reference \"" + reference + "\": expected best or machine");
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
      py::arg("job"), py::arg("kp_grid") = std::vector<double>{1, 0.5, 9},
      py::arg("kf_grid") = std::vector<double>{0, 0.1, 1.2}, py::arg("gain_step") = 0.03,
      py::arg("frequency_hz") = 10.0, py::arg("reference") = "best", py::arg("kp_range") = py::none(),
      py::arg("verify") = true, py::arg("progress") = py::none(),
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
        d["ceiling_s_mm"] =
            py::array_t<double>(static_cast<py::ssize_t>(r->ceiling.s_mm.size()), r->ceiling.s_mm.data());
        d["ceiling_feed_mm_per_s"] = py::array_t<double>(static_cast<py::ssize_t>(r->ceiling.feed_mm_per_s.size()),
                                                         r->ceiling.feed_mm_per_s.data());
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
