#include "sysid/identify_axes.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

namespace vmsim::sysid {

namespace {

IdData deviations(const PositionTrace& t, int axis) {
  IdData d;
  d.u = t.command.col(axis).array() - t.command(0, axis);
  d.y = t.actual.col(axis).array() - t.actual(0, axis);
  d.period_s = t.period_s;
  return d;
}

void check_period(const PositionTrace& t, const PositionTrace& first, const std::string& first_name) {
  if (std::abs(t.period_s - first.period_s) > 1e-6 * first.period_s)
    throw core::Error(core::located(t.source, 0, fmt::format("sampled every {} s, {} every {} s", t.period_s, first_name,
                                                             first.period_s)));
}

void check_axis(const PositionTrace& t, const std::string& axis) {
  if (t.axis_index(axis) < 0)
    throw core::Error(core::located(t.source, 0, fmt::format("--axis {}: the trace has no columns for it", axis)));
}

// Estimation and validation data of one axis (see the header for the split).
AxisData axis_data(const std::vector<PositionTrace>& traces, const PositionTrace* validation, std::size_t n_est,
                   const std::string& name) {
  const PositionTrace& trace = traces.front();
  const int ai = trace.axis_index(name);
  AxisData a;
  a.name = name;
  a.rotary = trace.rotary[static_cast<std::size_t>(ai)];
  a.rest_offset = std::abs(trace.command(0, ai) - trace.actual(0, ai));
  const IdData all = deviations(trace, ai);
  a.estimation = all;
  if (n_est > 1) {
    // Each trace its own experiment, as deviations from its own rest point.
    std::vector<IdData> parts;
    for (std::size_t i = 0; i < n_est; ++i) parts.push_back(deviations(traces[i], traces[i].axis_index(name)));
    a.estimation = concatenate(parts);
  }
  if (validation) {
    a.validation = deviations(*validation, validation->axis_index(name));
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

bool AxisData::starts_at_rest() const { return !(rest_offset > 1e-3 * (rotary ? 3.14159265358979 / 180.0 : 1.0)); }

IdentificationData prepare_identification(const std::vector<PositionTrace>& traces, const PositionTrace* validation,
                                          const AxesIdentificationOptions& options) {
  if (traces.empty()) throw core::Error("identification: at least one position trace is needed");
  const PositionTrace& trace = traces.front();
  for (std::size_t i = 1; i < traces.size(); ++i) check_period(traces[i], trace, trace.source);
  if (validation && std::abs(validation->period_s - trace.period_s) > 1e-6 * trace.period_s)
    throw core::Error(core::located(validation->source, 0, fmt::format("sampled every {} s, the trace every {} s",
                                                                       validation->period_s, trace.period_s)));
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
  for (const std::string& a : axes) d.axes.push_back(axis_data(traces, held, d.estimation_traces, a));
  return d;
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
    if (options.delay) o.nk = *options.delay;
    else if (options.orders) o.nk = select_delay(data.estimation, o.na, o.nb);
  } catch (const core::Error& e) {
    throw core::Error(core::located(source, 0, fmt::format("axis {}: {}", data.name, e.what())));
  }
  r.orders = o;
  for (ModelStructure s : options.structures) {
    const auto t0 = core::Clock::now();
    try {
      IdentifiedModel m = identify(s, data.estimation, o);
      const Validation v = validate(m, data.validation, options.lags, data.first_validation_sample);
      r.models.push_back({std::move(m), v, core::seconds_since(t0), 0});
    } catch (const core::Error& e) {
      throw core::Error(core::located(source, 0, fmt::format("axis {} {}: {}", data.name, structure_name(s), e.what())));
    }
  }
  std::vector<std::size_t> rank(r.models.size());
  for (std::size_t i = 0; i < rank.size(); ++i) rank[i] = i;
  // A model whose validation is not finite (a search that failed) ranks last.
  const auto key = [&](std::size_t i) {
    return std::isfinite(r.models[i].validation.mse) ? r.models[i].validation.mse : HUGE_VAL;
  };
  std::stable_sort(rank.begin(), rank.end(), [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  for (std::size_t k = 0; k < rank.size(); ++k) r.models[rank[k]].rank = static_cast<int>(k) + 1;
  r.chosen = rank.front();
  if (options.use)
    r.chosen = static_cast<std::size_t>(
        std::find(options.structures.begin(), options.structures.end(), *options.use) - options.structures.begin());
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
