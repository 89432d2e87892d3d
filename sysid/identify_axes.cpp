#include "sysid/identify_axes.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

namespace vmsim::sysid {

namespace {

// Over [k0, k0 + m): neither the command nor the encoder moves more than kRestTolerance.
bool still(const PositionTrace& t, int axis, Eigen::Index k0, Eigen::Index m) {
  if (k0 + m > t.t_s.size()) return false;
  const double tol = kRestTolerance * (t.rotary[static_cast<std::size_t>(axis)] ? 3.14159265358979 / 180.0 : 1.0);
  const auto u = t.command.col(axis).segment(k0, m).array(), y = t.actual.col(axis).segment(k0, m).array();
  return (u - u[0]).abs().maxCoeff() <= tol && (y - y[0]).abs().maxCoeff() <= tol;
}

struct RestPoint {
  bool at_rest = true;
  double u = 0.0, y = 0.0;  // subtracted from command and encoder
  double offset = 0.0;      // encoder - command at rest (moving start)
  std::string from;
};

RestPoint rest_point(const PositionTrace& t, int axis, const std::map<std::string, double>& given) {
  RestPoint r;
  r.u = t.command(0, axis);
  r.y = t.actual(0, axis);
  if (still(t, axis, 0, kRestSamples)) {
    r.from = "the first sample";
    return r;
  }
  r.at_rest = false;
  const auto g = given.find(t.axes[static_cast<std::size_t>(axis)]);
  if (g != given.end()) {
    r.offset = g->second;
    r.from = "--rest-offset";
  } else {
    r.from = "none: no still stretch in the trace, 0 assumed";
    for (Eigen::Index k = 0; k + kRestStretchSamples <= t.t_s.size(); k += kRestStretchSamples / 5)
      if (still(t, axis, k, kRestStretchSamples)) {
        r.offset =
            (t.actual.col(axis).segment(k, kRestStretchSamples) - t.command.col(axis).segment(k, kRestStretchSamples))
                .mean();
        r.from = fmt::format("the still stretch at t = {:.4g} s", t.t_s[k]);
        break;
      }
  }
  r.y = r.u + r.offset;
  return r;
}

IdData deviations(const PositionTrace& t, int axis, const RestPoint& r) {
  IdData d;
  d.u = t.command.col(axis).array() - r.u;
  d.y = t.actual.col(axis).array() - r.y;
  d.period_s = t.period_s;
  d.initial_state_estimated = !r.at_rest;
  d.y_reference = r.y;
  return d;
}

IdData deviations(const PositionTrace& t, int axis, const std::map<std::string, double>& given) {
  return deviations(t, axis, rest_point(t, axis, given));
}

void check_period(const PositionTrace& t, const PositionTrace& first, const std::string& first_name) {
  if (std::abs(t.period_s - first.period_s) > 1e-6 * first.period_s)
    throw core::Error(core::located(
        t.source, 0, fmt::format("sampled every {} s, {} every {} s", t.period_s, first_name, first.period_s)));
}

void check_axis(const PositionTrace& t, const std::string& axis) {
  if (t.axis_index(axis) < 0)
    throw core::Error(core::located(t.source, 0, fmt::format("--axis {}: the trace has no columns for it", axis)));
}

// Estimation and validation data of one axis (see the header for the split).
AxisData axis_data(const std::vector<PositionTrace>& traces, const PositionTrace* validation, std::size_t n_est,
                   const std::string& name, const std::map<std::string, double>& given) {
  const PositionTrace& trace = traces.front();
  const int ai = trace.axis_index(name);
  AxisData a;
  a.name = name;
  a.rotary = trace.rotary[static_cast<std::size_t>(ai)];
  a.first_sample_offset = std::abs(trace.command(0, ai) - trace.actual(0, ai));
  const RestPoint first = rest_point(trace, ai, given);
  const IdData all = deviations(trace, ai, first);
  a.estimation = all;
  a.at_rest = first.at_rest;
  if (!first.at_rest) {
    a.rest_offset = first.offset;
    a.rest_offset_from = first.from;
  }
  if (n_est > 1) {
    // Each trace its own experiment, as deviations from its own rest point.
    std::vector<IdData> parts;
    for (std::size_t i = 0; i < n_est; ++i) parts.push_back(deviations(traces[i], traces[i].axis_index(name), given));
    a.estimation = concatenate(parts);
  }
  if (validation) {
    a.validation = deviations(*validation, validation->axis_index(name), given);
  } else {
    const Eigen::Index half = all.u.size() / 2;
    a.estimation.u = all.u.head(half);
    a.estimation.y = all.y.head(half);
    a.validation = all;
    a.first_validation_sample = half;
  }
  return a;
}

}  // namespace

bool is_marginal(const drives::DiscreteTf& g) {
  const double r = drives::spectral_radius(g.a);
  return !(r <= kMarginalPoleMagnitude);
}

IdentificationData prepare_identification(const std::vector<PositionTrace>& traces, const PositionTrace* validation,
                                          const AxesIdentificationOptions& options) {
  if (traces.empty()) throw core::Error("identification: at least one position trace is needed");
  const PositionTrace& trace = traces.front();
  for (std::size_t i = 1; i < traces.size(); ++i) check_period(traces[i], trace, trace.source);
  if (validation && std::abs(validation->period_s - trace.period_s) > 1e-6 * trace.period_s)
    throw core::Error(
        core::located(validation->source, 0,
                      fmt::format("sampled every {} s, the trace every {} s", validation->period_s, trace.period_s)));
  IdentificationData d;
  d.source = trace.source;
  d.period_s = trace.period_s;
  d.estimation_traces = traces.size();
  const PositionTrace* held = validation;
  if (validation) {
    d.validation = ValidationData::SeparateTrace;
  } else if (traces.size() > 1) {
    held = &traces.back();
    d.estimation_traces = traces.size() - 1;
    d.validation = ValidationData::HeldOutTrace;
  }
  for (std::size_t i = 0; i < d.estimation_traces; ++i)
    d.estimation_files.push_back(std::filesystem::path(traces[i].source).filename().string());
  const std::vector<std::string> axes = options.axes.empty() ? trace.axes : options.axes;
  for (const std::string& a : axes) {
    for (const PositionTrace& t : traces) check_axis(t, a);
    if (validation) check_axis(*validation, a);
  }
  for (const auto& [name, offset] : options.rest_offsets)
    if (std::find(axes.begin(), axes.end(), name) == axes.end())
      throw core::Error(
          fmt::format("--rest-offset {}: no such axis is identified (axes: {})", name, fmt::join(axes, ", ")));
  for (const std::string& a : axes)
    d.axes.push_back(axis_data(traces, held, d.estimation_traces, a, options.rest_offsets));
  return d;
}

void rank_models(std::vector<ModelResult>& models) {
  std::vector<std::size_t> rank(models.size());
  for (std::size_t i = 0; i < rank.size(); ++i) rank[i] = i;
  // A marginal or unstable model ranks after every stable one; a model whose validation is not finite (a search
  // that failed) ranks last.
  const auto key = [&](std::size_t i) {
    const double mse = models[i].validation.mse;
    return std::make_pair(models[i].marginal || !std::isfinite(mse), std::isfinite(mse) ? mse : HUGE_VAL);
  };
  std::stable_sort(rank.begin(), rank.end(), [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  for (std::size_t k = 0; k < rank.size(); ++k) models[rank[k]].rank = static_cast<int>(k) + 1;
}

AxisIdentification identify_axis(const AxisData& data, const std::string& source,
                                 const AxesIdentificationOptions& options) {
  if (options.use &&
      std::find(options.structures.begin(), options.structures.end(), *options.use) == options.structures.end())
    throw core::Error(fmt::format("identification: the structure to use ({}) is not among those identified",
                                  structure_name(*options.use)));
  AxisIdentification r;
  r.name = data.name;
  r.rotary = data.rotary;
  ModelOrders o = options.orders.value_or(ModelOrders{});
  try {
    if (!options.orders) {
      o = select_orders_bic(data.estimation);
      o.nc = options.nc;
    }
    if (options.delay)
      o.nk = *options.delay;
    else if (options.orders)
      o.nk = select_delay(data.estimation, o.na, o.nb);
  } catch (const core::Error& e) {
    throw core::Error(core::located(source, 0, fmt::format("axis {}: {}", data.name, e.what())));
  }
  r.orders = o;
  for (ModelStructure s : options.structures) {
    const auto t0 = core::Clock::now();
    try {
      IdentifiedModel m = identify(s, data.estimation, o);
      const Validation v = validate(m, data.validation, options.lags, data.first_validation_sample);
      const bool marginal = is_marginal(m.g);
      r.models.push_back({std::move(m), v, core::seconds_since(t0), 0, marginal});
    } catch (const core::Error& e) {
      throw core::Error(
          core::located(source, 0, fmt::format("axis {} {}: {}", data.name, structure_name(s), e.what())));
    }
  }
  rank_models(r.models);
  for (std::size_t i = 0; i < r.models.size(); ++i)
    if (r.models[i].rank == 1) r.chosen = i;
  if (options.use)
    r.chosen = static_cast<std::size_t>(std::find(options.structures.begin(), options.structures.end(), *options.use) -
                                        options.structures.begin());
  return r;
}

IdentifiedAxis chosen_axis(const AxisIdentification& axis) {
  const ModelResult& c = axis.models[axis.chosen];
  IdentifiedAxis ia;
  ia.name = axis.name;
  ia.structure = c.model.structure;
  ia.tf = c.model.g;
  ia.c = c.model.c;
  ia.fit_percent = c.validation.fit_percent;
  ia.tracking_fit_percent = c.validation.tracking_fit_percent;
  return ia;
}

AxisModelFile axis_model_file(const IdentificationData& data, const std::vector<AxisIdentification>& axes) {
  AxisModelFile file;
  file.period_s = data.period_s;
  for (std::size_t i = 0; i < data.estimation_files.size(); ++i)
    file.trace += (i ? ", " : "") + data.estimation_files[i];
  for (const AxisIdentification& a : axes) file.axes.push_back(chosen_axis(a));
  return file;
}

AxesIdentification identify_axes(const std::vector<PositionTrace>& traces, const PositionTrace* validation,
                                 const AxesIdentificationOptions& options) {
  AxesIdentification r;
  r.data = prepare_identification(traces, validation, options);
  for (const AxisData& a : r.data.axes) r.axes.push_back(identify_axis(a, r.data.source, options));
  r.file = axis_model_file(r.data, r.axes);
  return r;
}

}  // namespace vmsim::sysid
