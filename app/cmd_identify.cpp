// vmsim identify --trace TRACE.csv: each axis's discrete transfer function from command to encoder position (seed
// 001 sections 2-3): ARX, ARMAX and OE fitted on the estimation data, validated on separate data, ranked by the
// validation MSE as the predictive-compensation paper Table 2, the chosen one written to axis_models.toml for jobs to run on.
#include "app/commands_sysid.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/sha256.hpp"
#include "sysid/axis_model_file.hpp"
#include "sysid/position_trace.hpp"
#include "sysid/sysid.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

namespace vmsim::app {

namespace {

using Clock = std::chrono::steady_clock;

sysid::ModelOrders parse_orders(const std::string& s, int nc, bool& automatic) {
  automatic = s == "auto";
  sysid::ModelOrders o;
  o.nc = nc;
  if (automatic) return o;
  const auto comma = s.find(',');
  const auto bad = [&] {
    throw core::Error(fmt::format("--orders '{}': expected NB,NA (numerator and denominator orders, e.g. 2,5 as seed "
                                  "001 section 2.2) or auto",
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

sysid::IdData deviations(const sysid::PositionTrace& t, int axis) {
  sysid::IdData d;
  d.u = t.command.col(axis).array() - t.command(0, axis);
  d.y = t.actual.col(axis).array() - t.actual(0, axis);
  d.period_s = t.period_s;
  return d;
}

nlohmann::json poly_json(const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

}  // namespace

int run_identify(const IdentifyArgs& args) {
  const auto t_start = Clock::now();
  // Options first: a bad option must fail before any reading or writing.
  std::vector<sysid::ModelStructure> structures;
  if (args.structure == "all") structures = {sysid::ModelStructure::Arx, sysid::ModelStructure::Armax, sysid::ModelStructure::Oe};
  else if (auto s = sysid::parse_structure(args.structure)) structures = {*s};
  else throw core::Error(fmt::format("--structure '{}': expected arx, armax, oe or all", args.structure));
  std::optional<sysid::ModelStructure> use;
  if (args.use != "best") {
    use = sysid::parse_structure(args.use);
    if (!use || std::find(structures.begin(), structures.end(), *use) == structures.end())
      throw core::Error(fmt::format("--use '{}': expected best or one of the structures identified", args.use));
  }
  if (args.nc < 0 || args.nc > 30) throw core::Error(fmt::format("--nc {}: expected 0 to 30", args.nc));
  bool auto_orders = false;
  const sysid::ModelOrders given = parse_orders(args.orders, args.nc, auto_orders);
  std::optional<int> delay;
  if (args.delay != "auto") {
    try {
      std::size_t p = 0;
      delay = std::stoi(args.delay, &p);
      if (p != args.delay.size()) throw std::invalid_argument("");
    } catch (const std::logic_error&) {
      throw core::Error(fmt::format("--delay '{}': expected a number of samples >= 1, or auto", args.delay));
    }
    if (*delay < 1 || *delay > 100) throw core::Error(fmt::format("--delay {}: expected 1 to 100 samples", *delay));
  }

  if (args.traces.empty()) throw core::Error("--trace: at least one position trace is needed");
  std::vector<sysid::PositionTrace> traces;
  for (const auto& p : args.traces) traces.push_back(sysid::read_position_trace_csv(p));
  const sysid::PositionTrace& trace = traces.front();
  for (std::size_t i = 1; i < traces.size(); ++i)
    if (std::abs(traces[i].period_s - trace.period_s) > 1e-6 * trace.period_s)
      throw core::Error(core::located(args.traces[i].string(), 0,
                                      fmt::format("sampled every {} s, {} every {} s", traces[i].period_s,
                                                  args.traces.front().string(), trace.period_s)));
  std::optional<sysid::PositionTrace> vtrace;
  std::size_t n_est = traces.size();  // traces the estimation uses (the rest: the last one, held out)
  if (args.validate) {
    vtrace = sysid::read_position_trace_csv(*args.validate);
    if (std::abs(vtrace->period_s - trace.period_s) > 1e-6 * trace.period_s)
      throw core::Error(core::located(args.validate->string(), 0,
                                      fmt::format("sampled every {} s, the trace every {} s", vtrace->period_s, trace.period_s)));
  } else if (traces.size() > 1) {
    vtrace = traces.back();
    n_est = traces.size() - 1;
  }
  std::vector<std::string> axes = args.axes.empty() ? trace.axes : args.axes;
  for (const auto& a : axes) {
    for (const auto& t : traces)
      if (t.axis_index(a) < 0)
        throw core::Error(core::located(t.source, 0, fmt::format("--axis {}: the trace has no columns for it", a)));
    if (vtrace && vtrace->axis_index(a) < 0)
      throw core::Error(core::located(vtrace->source, 0, fmt::format("--axis {}: the trace has no columns for it", a)));
  }
  const std::filesystem::path dir = args.out_dir.value_or(std::filesystem::current_path());

  nlohmann::json report;
  report["vmsim"] = VMSIM_VERSION;
  report["command"] = "identify";
  report["inputs"]["trace"] = {{"path", args.traces.front().string()}, {"sha256", core::sha256_file_hex(args.traces.front())}};
  report["inputs"]["traces"] = nlohmann::json::array();
  for (std::size_t i = 0; i < args.traces.size(); ++i)
    report["inputs"]["traces"].push_back({{"path", args.traces[i].string()},
                                          {"sha256", core::sha256_file_hex(args.traces[i])},
                                          {"use", i < n_est ? "estimation" : "validation"}});
  if (args.validate)
    report["inputs"]["validation_trace"] = {{"path", args.validate->string()}, {"sha256", core::sha256_file_hex(*args.validate)}};
  report["period_s"] = trace.period_s;
  report["conditioning"] =
      "deviations from the first (rest) sample of command and encoder, one common scale for both; QR least squares";
  report["orders_from"] = auto_orders ? "BIC over ARX fits (na 1-8, nb 1-4, nk 1-5)" : "given (the predictive-compensation paper section 2.2: nb 2, na 5)";
  report["validation"] = args.validate ? "separate trace"
                         : vtrace    ? "the last trace, held out"
                                     : "the trace's second half (model simulated over the whole record)";
  report["estimation"] = n_est > 1 ? fmt::format("{} traces as separate experiments (no regressor, filter or simulation "
                                                 "crosses a trace boundary)",
                                                 n_est)
                                   : std::string("one trace");

  sysid::AxisModelFile file;
  file.period_s = trace.period_s;
  file.trace = args.traces.front().filename().string();
  for (std::size_t i = 1; i < n_est; ++i) file.trace += ", " + args.traces[i].filename().string();
  std::printf("axis  structure  na nb nc nk   fit %%      tracking fit %%  1-R2        MSE (mm2|deg2)  white  rank\n");
  for (const std::string& name : axes) {
    const int ai = trace.axis_index(name);
    const bool rotary = trace.rotary[static_cast<std::size_t>(ai)];
    const sysid::IdData all = deviations(trace, ai);
    sysid::IdData est = all;
    Eigen::Index first_val = 0;
    sysid::IdData val;
    if (n_est > 1) {
      // Each trace its own experiment, as deviations from its own rest point.
      std::vector<sysid::IdData> parts;
      for (std::size_t i = 0; i < n_est; ++i) parts.push_back(deviations(traces[i], traces[i].axis_index(name)));
      est = sysid::concatenate(parts);
    }
    if (vtrace) {
      val = deviations(*vtrace, vtrace->axis_index(name));
    } else {
      const Eigen::Index half = all.u.size() / 2;
      est.u = all.u.head(half);
      est.y = all.y.head(half);
      val = all;
      first_val = half;
    }
    if (std::abs(trace.command(0, ai) - trace.actual(0, ai)) > 1e-3 * (rotary ? 3.14159265358979 / 180.0 : 1.0))
      std::fprintf(stderr, "vmsim: warning: axis %s: the trace does not start at rest (command and encoder differ by "
                           "%.4g); identification assumes it does\n",
                   name.c_str(), std::abs(trace.command(0, ai) - trace.actual(0, ai)));
    sysid::ModelOrders o = given;
    try {
      if (auto_orders) {
        o = sysid::select_orders_bic(est);
        o.nc = args.nc;
      }
      if (delay) o.nk = *delay;
      else if (!auto_orders) o.nk = sysid::select_delay(est, o.na, o.nb);
    } catch (const core::Error& e) {
      throw core::Error(core::located(trace.source, 0, fmt::format("axis {}: {}", name, e.what())));
    }

    struct Row { sysid::IdentifiedModel m; sysid::Validation v; double seconds; };
    std::vector<Row> rows;
    for (sysid::ModelStructure s : structures) {
      const auto t0 = Clock::now();
      try {
        sysid::IdentifiedModel m = sysid::identify(s, est, o);
        const sysid::Validation v = sysid::validate(m, val, 25, first_val);
        rows.push_back({std::move(m), v, std::chrono::duration<double>(Clock::now() - t0).count()});
      } catch (const core::Error& e) {
        throw core::Error(core::located(trace.source, 0, fmt::format("axis {} {}: {}", name, sysid::structure_name(s), e.what())));
      }
    }
    std::vector<std::size_t> rank(rows.size());
    for (std::size_t i = 0; i < rank.size(); ++i) rank[i] = i;
    // A model whose validation is not finite (a search that failed) ranks last.
    auto key = [&](std::size_t i) { return std::isfinite(rows[i].v.mse) ? rows[i].v.mse : HUGE_VAL; };
    std::stable_sort(rank.begin(), rank.end(), [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
    std::vector<int> place(rows.size());
    for (std::size_t r = 0; r < rank.size(); ++r) place[rank[r]] = static_cast<int>(r) + 1;

    const double f2 = rotary ? std::pow(180.0 / 3.14159265358979323846, 2) : 1.0;
    nlohmann::json jaxis;
    jaxis["unit"] = rotary ? "deg" : "mm";
    jaxis["orders"] = {{"na", o.na}, {"nb", o.nb}, {"nc", o.nc}, {"nk", o.nk}};
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const Row& r = rows[i];
      const char* sn = sysid::structure_name(r.m.structure);
      std::printf("%-4s  %-9s  %2d %2d %2s %2d   %9.5f  %9.3f       %.3e   %.3e       %-5s  %d\n", name.c_str(), sn,
                  r.m.orders.na, r.m.orders.nb,
                  r.m.structure == sysid::ModelStructure::Armax ? std::to_string(r.m.orders.nc).c_str() : "-",
                  r.m.orders.nk, r.v.fit_percent, r.v.tracking_fit_percent, 1.0 - r.v.r2, r.v.mse * f2,
                  r.v.white ? "yes" : "no", place[i]);
      nlohmann::json jm = {
          {"rank", place[i]},
          {"b", poly_json(r.m.g.b)},
          {"a", poly_json(r.m.g.a)},
          {"nk", r.m.g.nk},
          {"static_gain", r.m.g.static_gain()},
          {"largest_pole_magnitude", drives::spectral_radius(r.m.g.a)},
          {"estimation_loss", r.m.loss * f2},
          {"iterations", r.m.iterations},
          {"converged", r.m.converged},
          {"seconds", r.seconds},
          {"validation",
           {{"fit_percent", r.v.fit_percent},
            {"tracking_fit_percent", r.v.tracking_fit_percent},
            {"r2", r.v.r2},
            {"one_minus_r2", 1.0 - r.v.r2},
            {"mse", r.v.mse * f2},
            {"max_abs_error", r.v.max_abs_error * std::sqrt(f2)},
            {"whiteness", {{"portmanteau_q", r.v.portmanteau_q}, {"limit_99", r.v.portmanteau_limit}, {"lags", r.v.lags},
                           {"max_abs_autocorrelation", r.v.max_abs_autocorrelation},
                           {"band_99", r.v.whiteness_bound}, {"white", r.v.white}}}}}};
      if (r.m.c.size() > 0) jm["c"] = poly_json(r.m.c);
      jaxis["models"][sn] = jm;
    }
    const std::size_t chosen = use ? static_cast<std::size_t>(
                                         std::find_if(rows.begin(), rows.end(), [&](const Row& r) { return r.m.structure == *use; }) -
                                         rows.begin())
                                   : rank.front();
    const Row& c = rows[chosen];
    jaxis["chosen"] = sysid::structure_name(c.m.structure);
    report["axes"][name] = jaxis;
    sysid::IdentifiedAxis ia;
    ia.name = name;
    ia.structure = c.m.structure;
    ia.tf = c.m.g;
    ia.c = c.m.c;
    ia.fit_percent = c.v.fit_percent;
    ia.tracking_fit_percent = c.v.tracking_fit_percent;
    file.axes.push_back(ia);
  }

  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
  std::vector<std::string> comments = {
      "Identified axis models (the predictive-compensation paper): discrete transfer functions from command to encoder position,",
      "A(q) y(k) = B(q) u(k - nk), A = 1 + a1 q^-1 + ..., B = b1 + b2 q^-1 + ...; u, y deviations from the rest point.",
      "Written by vmsim identify from " + file.trace + "; keys in parts/README.md."};
  sysid::save_axis_models(dir / "axis_models.toml", file, comments);
  report["files"] = {"axis_models.toml", "report.json"};
  report["timings_s"] = {{"total", std::chrono::duration<double>(Clock::now() - t_start).count()}};
  write_report(dir / "report.json", report);  // and report.html
  std::printf("chosen:");
  for (const auto& a : file.axes) std::printf(" %s %s", a.name.c_str(), sysid::structure_name(a.structure));
  std::printf(" (lowest validation MSE%s)\nwrote %s (axis_models.toml, report.json)\n", use ? ", overridden by --use" : "",
              dir.string().c_str());
  return 0;
}

}  // namespace vmsim::app
