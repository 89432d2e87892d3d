// vmsim identify --trace TRACE.csv: each axis's discrete transfer function from command to encoder position (the
// predictive-compensation paper sections 2-3) through sysid::identify_axis; the chosen models written to
// axis_models.toml for jobs to run on, every model's figures to report.json and a table on stdout.
#include "app/commands_sysid.hpp"
#include "core/units.hpp"
#include "app/report.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/hash.hpp"
#include "core/timing.hpp"
#include "sysid/axis_model_file.hpp"
#include "sysid/identify_axes.hpp"
#include "sysid/position_trace.hpp"
#include "sysid/trace_formats.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace vmsim::app {

namespace {

using core::units::kPi;

std::optional<sysid::ModelOrders> parse_orders(const std::string& s, int nc) {
  if (s == "auto") return std::nullopt;
  sysid::ModelOrders o;
  o.nc = nc;
  const auto comma = s.find(',');
  const auto bad = [&] {
    throw core::Error(
        fmt::format("--orders '{}': expected NB,NA (numerator and denominator orders, e.g. 2,5 as the "
                    "predictive-compensation paper, section 2.2) or auto",
                    s));
  };
  if (comma == std::string::npos) bad();
  try {
    std::size_t p1 = 0, p2 = 0;
    const std::string a = s.substr(0, comma), b = s.substr(comma + 1);
    o.nb = std::stoi(a, &p1);
    o.na = std::stoi(b, &p2);
    if (p1 != a.size() || p2 != b.size()) bad();
  } catch (const std::logic_error&) {
    bad();
  }
  if (o.nb < 1 || o.nb > 30 || o.na < 0 || o.na > 30)
    throw core::Error(fmt::format("--orders '{}': NB must be in [1, 30] and NA in [0, 30]", s));
  return o;
}

std::optional<int> parse_delay(const std::string& s) {
  if (s == "auto") return std::nullopt;
  int delay = 0;
  try {
    std::size_t p = 0;
    delay = std::stoi(s, &p);
    if (p != s.size()) throw std::invalid_argument("");
  } catch (const std::logic_error&) {
    throw core::Error(fmt::format("--delay '{}': expected a number of samples >= 1, or auto", s));
  }
  if (delay < 1 || delay > 100) throw core::Error(fmt::format("--delay {}: expected 1 to 100 samples", delay));
  return delay;
}

// Options first: a bad option must fail before any reading or writing.
sysid::AxesIdentificationOptions parse_options(const IdentifyArgs& args) {
  sysid::AxesIdentificationOptions o;
  if (args.structure != "all") {
    const auto s = sysid::parse_structure(args.structure);
    if (!s) throw core::Error(fmt::format("--structure '{}': expected arx, armax, oe or all", args.structure));
    o.structures = {*s};
  }
  if (args.use != "best") {
    o.use = sysid::parse_structure(args.use);
    if (!o.use || std::find(o.structures.begin(), o.structures.end(), *o.use) == o.structures.end())
      throw core::Error(fmt::format("--use '{}': expected best or one of the structures identified", args.use));
  }
  if (args.nc < 0 || args.nc > 30) throw core::Error(fmt::format("--nc {}: expected 0 to 30", args.nc));
  o.nc = args.nc;
  o.orders = parse_orders(args.orders, args.nc);
  o.delay = parse_delay(args.delay);
  o.axes = args.axes;
  for (const std::string& r : args.rest_offsets) {
    const auto eq = r.find('=');
    const std::string axis = eq == std::string::npos ? "" : r.substr(0, eq);
    const auto value = eq == std::string::npos ? std::nullopt : core::parse_number(r.substr(eq + 1));
    if (axis.size() != 1 || std::string("XYZABC").find(axis) == std::string::npos || !value)
      throw core::Error(fmt::format("--rest-offset '{}': expected AXIS=VALUE (mm, or deg on A B C), e.g. X=0.005", r));
    o.rest_offsets[axis] = *value * (std::string("ABC").find(axis) != std::string::npos ? kPi / 180.0 : 1.0);
  }
  if (args.traces.empty()) throw core::Error("--trace: at least one position trace is needed");
  return o;
}

sysid::TraceChannels trace_channels(const IdentifyArgs& args) {
  sysid::TraceChannels ch;
  for (const std::string& c : args.channels) ch.pins.push_back(sysid::parse_pin_pair(c));
  if (args.mat) ch.variables = sysid::parse_mat_variables(*args.mat);
  ch.unit = args.trace_unit;
  return ch;
}

// What the readers did to a trace's time stamps, said once per trace (and in report.json).
nlohmann::json sampling_json(const sysid::PositionTrace& t) {
  const double jitter = t.max_jitter_s / t.period_s;
  if (t.resampled)
    std::fprintf(stderr,
                 "vmsim: warning: %s: time stamps jitter by up to %.3g s (%.3g %% of the %.6g s period, above "
                 "%.3g %%): resampled onto the mean period by linear interpolation\n",
                 t.source.c_str(), t.max_jitter_s, 100.0 * jitter, t.period_s, 100.0 * sysid::kJitterTolerance);
  else if (jitter > 1e-6)
    std::fprintf(stderr,
                 "vmsim: note: %s: time stamps jitter by up to %.3g s (%.3g %% of the period, within %.3g %%): "
                 "taken as sampled every %.9g s\n",
                 t.source.c_str(), t.max_jitter_s, 100.0 * jitter, 100.0 * sysid::kJitterTolerance, t.period_s);
  return {{"samples", t.t_s.size()},
          {"period_s", t.period_s},
          {"max_jitter_s", t.max_jitter_s},
          {"jitter_tolerance_of_period", sysid::kJitterTolerance},
          {"resampled", t.resampled}};
}

nlohmann::json poly_json(const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

nlohmann::json inputs_json(const IdentifyArgs& args, std::size_t n_est, const std::vector<nlohmann::json>& sampling) {
  nlohmann::json in;
  in["trace"] = {{"path", args.traces.front().string()}, {"sha256", core::sha256_file_hex(args.traces.front())}};
  in["traces"] = nlohmann::json::array();
  for (std::size_t i = 0; i < args.traces.size(); ++i)
    in["traces"].push_back({{"path", args.traces[i].string()},
                            {"sha256", core::sha256_file_hex(args.traces[i])},
                            {"format", sysid::trace_format_name(sysid::detect_trace_format(args.traces[i]))},
                            {"sampling", sampling.at(i)},
                            {"use", i < n_est ? "estimation" : "validation"}});
  if (args.validate)
    in["validation_trace"] = {{"path", args.validate->string()}, {"sha256", core::sha256_file_hex(*args.validate)}};
  return in;
}

nlohmann::json header_json(const IdentifyArgs& args, const sysid::IdentificationData& d,
                           const std::vector<nlohmann::json>& sampling) {
  nlohmann::json report;
  report["vmsim"] = VMSIM_VERSION;
  report["command"] = "identify";
  report["inputs"] = inputs_json(args, d.estimation_traces, sampling);
  report["period_s"] = d.period_s;
  report["conditioning"] =
      "deviations from the rest point (a trace that starts at rest: its first sample of command and encoder; one "
      "that starts mid-motion: its first command, the encoder's less the rest offset, with the initial state and an "
      "output offset estimated), one common scale for both; QR least squares";
  report["orders_from"] = args.orders == "auto" ? "BIC over ARX fits (na 1-8, nb 1-4, nk 1-5)"
                                                : "given (the predictive-compensation paper section 2.2: nb 2, na 5)";
  report["validation"] = d.validation == sysid::ValidationData::SeparateTrace ? "separate trace"
                         : d.validation == sysid::ValidationData::HeldOutTrace
                             ? "the last trace, held out"
                             : "the trace's second half (model simulated over the whole record)";
  report["estimation"] = d.estimation_traces > 1 ? fmt::format(
                                                       "{} traces as separate experiments (no regressor, "
                                                       "filter or simulation crosses a trace boundary)",
                                                       d.estimation_traces)
                                                 : std::string("one trace");
  return report;
}

// One model's figures; f2 converts rad^2 to deg^2 on a rotary axis.
nlohmann::json model_json(const sysid::ModelResult& r, double f2) {
  const sysid::IdentifiedModel& m = r.model;
  const sysid::Validation& v = r.validation;
  nlohmann::json jm = {{"rank", r.rank},
                       {"b", poly_json(m.g.b)},
                       {"a", poly_json(m.g.a)},
                       {"nk", m.g.nk},
                       {"static_gain", m.g.static_gain()},
                       {"largest_pole_magnitude", drives::spectral_radius(m.g.a)},
                       {"marginal", r.marginal},
                       {"estimation_loss", m.loss * f2},
                       {"iterations", m.iterations},
                       {"converged", m.converged},
                       {"seconds", r.seconds},
                       {"validation",
                        {{"fit_percent", v.fit_percent},
                         {"tracking_fit_percent", v.tracking_fit_percent},
                         {"r2", v.r2},
                         {"one_minus_r2", 1.0 - v.r2},
                         {"mse", v.mse * f2},
                         {"max_abs_error", v.max_abs_error * std::sqrt(f2)},
                         {"relative_error_percent", v.relative_error_percent},
                         {"whiteness",
                          {{"portmanteau_q", v.portmanteau_q},
                           {"limit_99", v.portmanteau_limit},
                           {"lags", v.lags},
                           {"max_abs_autocorrelation", v.max_abs_autocorrelation},
                           {"band_99", v.whiteness_bound},
                           {"white", v.white}}}}}};
  if (m.c.size() > 0) jm["c"] = poly_json(m.c);
  return jm;
}

// The axis's rows of the table on stdout, and its part of report.json.
nlohmann::json print_axis(const sysid::AxisIdentification& a, const sysid::AxisData& d) {
  const double f2 = a.rotary ? std::pow(180.0 / kPi, 2) : 1.0;
  nlohmann::json jaxis;
  jaxis["unit"] = a.rotary ? "deg" : "mm";
  jaxis["starts_at_rest"] = d.at_rest;
  if (!d.at_rest)
    jaxis["rest_offset"] = {
        {"value", d.rest_offset * std::sqrt(f2)}, {"from", d.rest_offset_from}, {"initial_state", "estimated"}};
  jaxis["orders"] = {{"na", a.orders.na}, {"nb", a.orders.nb}, {"nc", a.orders.nc}, {"nk", a.orders.nk}};
  for (const sysid::ModelResult& r : a.models) {
    const sysid::IdentifiedModel& m = r.model;
    const char* sn = sysid::structure_name(m.structure);
    std::printf("%-4s  %-9s  %2d %2d %2s %2d   %9.5f  %9.3f       %.3e   %.3e       %-5s  %d%s\n", a.name.c_str(), sn,
                m.orders.na, m.orders.nb,
                m.structure == sysid::ModelStructure::Armax ? std::to_string(m.orders.nc).c_str() : "-", m.orders.nk,
                r.validation.fit_percent, r.validation.tracking_fit_percent, 1.0 - r.validation.r2,
                r.validation.mse * f2, r.validation.white ? "yes" : "no", r.rank, r.marginal ? "  marginal" : "");
    jaxis["models"][sn] = model_json(r, f2);
  }
  jaxis["chosen"] = sysid::structure_name(a.models[a.chosen].model.structure);
  for (const sysid::ModelResult& r : a.models)
    if (r.marginal)
      std::fprintf(
          stderr,
          "vmsim: warning: axis %s: the %s model has a pole of magnitude %.8f (marginal or unstable): "
          "ranked last%s\n",
          a.name.c_str(), sysid::structure_name(r.model.structure), drives::spectral_radius(r.model.g.a),
          &r == &a.models[a.chosen] ? ", and yet written to axis_models.toml (--use, or no stable model)" : "");
  return jaxis;
}

void write_model_file(const std::filesystem::path& dir, const sysid::AxisModelFile& file) {
  core::create_result_subdir(dir);
  const std::vector<std::string> comments = {
      "Identified axis models (the predictive-compensation paper): discrete transfer functions from command to "
      "encoder position,",
      "A(q) y(k) = B(q) u(k - nk), A = 1 + a1 q^-1 + ..., B = b1 + b2 q^-1 + ...; u, y deviations from the rest point.",
      "Written by vmsim identify from " + file.trace + "; keys in parts/README.md."};
  sysid::save_axis_models(dir / "axis_models.toml", file, comments);
}

}  // namespace

int run_identify(const IdentifyArgs& args) {
  const auto t_start = core::Clock::now();
  for (const auto& p : args.traces) require_utf8_input(p, "--trace");
  if (args.validate) require_utf8_input(*args.validate, "--validate");
  const sysid::AxesIdentificationOptions options = parse_options(args);
  const sysid::TraceChannels channels = trace_channels(args);
  std::vector<sysid::PositionTrace> traces;
  std::vector<nlohmann::json> sampling;
  for (const auto& p : args.traces) {
    traces.push_back(sysid::read_position_trace(p, channels));
    sampling.push_back(sampling_json(traces.back()));
  }
  std::optional<sysid::PositionTrace> vtrace;
  if (args.validate) {
    vtrace = sysid::read_position_trace(*args.validate, channels);
    sampling_json(*vtrace);
  }
  const sysid::IdentificationData data = sysid::prepare_identification(traces, vtrace ? &*vtrace : nullptr, options);
  // Locked now, written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(out_dir_or_default(args.out_dir, args.traces.front().stem().string(), "identify"),
                      "vmsim identify");
  const std::filesystem::path dir = out.path();

  nlohmann::json report = header_json(args, data, sampling);
  std::vector<sysid::AxisIdentification> axes;
  std::printf("axis  structure  na nb nc nk   fit %%      tracking fit %%  1-R2        MSE (mm2|deg2)  white  rank\n");
  for (const sysid::AxisData& a : data.axes) {
    if (!a.starts_at_rest())
      std::fprintf(stderr,
                   "vmsim: note: axis %s: the trace does not start at rest: rest offset %.6g %s from %s; the "
                   "initial state is estimated\n",
                   a.name.c_str(), a.rest_offset * (a.rotary ? 180.0 / kPi : 1.0), a.rotary ? "deg" : "mm",
                   a.rest_offset_from.c_str());
    axes.push_back(sysid::identify_axis(a, data.source, options));
    report["axes"][a.name] = print_axis(axes.back(), a);
  }
  const sysid::AxisModelFile file = sysid::axis_model_file(data, axes);
  write_model_file(dir, file);
  report["files"] = {"axis_models.toml", "report.json"};
  report["timings_s"] = {{"total", core::seconds_since(t_start)}};
  write_report(dir / "report.json", report);  // and report.html
  out.commit();
  std::printf("chosen:");
  for (const auto& a : file.axes) std::printf(" %s %s", a.name.c_str(), sysid::structure_name(a.structure));
  std::printf(" (lowest validation MSE, marginal models last%s)\nwrote %s (axis_models.toml, report.json)\n",
              options.use ? ", overridden by --use" : "", out.target().string().c_str());
  return 0;
}

}  // namespace vmsim::app
