// Drive simulation throughput: simulated seconds per wall second (x real time) of simulate_axes on the Mikron
// UCP 710's five cascade drives (current loop 16 kHz, velocity loop 8 kHz, position loop 1 kHz), one thread, on
// the interpolator's setpoints for the plane-cylinder part's 10 m/min pass. Target (drives issue): >= 100x real
// time for 5 axes on one core. Figures: bench/README.md.
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/simulate.hpp"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <filesystem>

namespace {

using namespace vmsim;

const std::filesystem::path kSource = VMSIM_SOURCE_DIR;

struct Stream {
  core::Job job;
  core::Setpoints setpoints;
};

const Stream& plane_cylinder_fast() {
  static const Stream s = [] {
    Stream out{core::load_job(kSource / "parts/plane_cylinder/job_fast.toml"), {}};
    program::ProgramOptions po;
    po.tool_table = out.job.tool_table_file;
    po.no_motion_mcodes = out.job.no_motion_mcodes;
    const core::ToolPath tp =
        motion::toolpath_in_axis_space(program::read_program(out.job.program_file, po), out.job.machine);
    motion::InterpOptions io;
    io.period_s = out.job.interp.period_s;
    io.tolerance_mm = out.job.interp.tolerance_mm;
    out.setpoints = motion::interpolate(tp, out.job.machine, io).setpoints;
    return out;
  }();
  return s;
}

void run_simulate(benchmark::State& state, bool trace) {
  const Stream& s = plane_cylinder_fast();
  omp_set_num_threads(1);
  drives::SimulateOptions o;
  o.full_rate_trace = trace;
  double simulated = 0.0;
  long long inner_steps = 0;
  for (auto _ : state) {
    drives::AxisResponse r = drives::simulate_axes(s.setpoints, s.job.machine, o);
    simulated = static_cast<double>(r.samples() - 1) * r.period_s;
    inner_steps = 0;
    for (const auto& ax : s.job.machine.axes)
      if (ax.drive) inner_steps += static_cast<long long>(std::llround(simulated / ax.drive->current_period_s));
    benchmark::DoNotOptimize(r.position.data());
  }
  const double it = static_cast<double>(state.iterations());
  state.counters["axes"] = static_cast<double>(s.job.machine.axes.size());
  state.counters["simulated_s"] = simulated;
  state.counters["x_real_time"] = benchmark::Counter(it * simulated, benchmark::Counter::kIsRate);
  state.counters["current_steps/s"] =
      benchmark::Counter(it * static_cast<double>(inner_steps), benchmark::Counter::kIsRate);
}

void BM_Drives_PlaneCylinderFast_5Axes(benchmark::State& state) { run_simulate(state, false); }
BENCHMARK(BM_Drives_PlaneCylinderFast_5Axes)->Unit(benchmark::kMillisecond);

void BM_Drives_PlaneCylinderFast_5Axes_FullRateTrace(benchmark::State& state) { run_simulate(state, true); }
BENCHMARK(BM_Drives_PlaneCylinderFast_5Axes_FullRateTrace)->Unit(benchmark::kMillisecond);

// One cascade axis (Mikron X, with Coulomb friction) stepped directly: the cost of one Te = 16 current periods.
void BM_CascadeAxis_Step(benchmark::State& state) {
  const core::Machine& m = plane_cylinder_fast().job.machine;
  drives::CascadeAxis ax(*m.axes[0].drive, 1e-3, m.axes[0].kind);
  ax.reset(0.0);
  drives::AxisCommand c;
  long long k = 0;
  for (auto _ : state) {
    const double t = static_cast<double>(k++) * 1e-3;
    c.position = 10.0 * std::sin(t);  // keeps reversing through the friction band
    c.velocity = 10.0 * std::cos(t);
    benchmark::DoNotOptimize(ax.step(c));
  }
  state.counters["x_real_time"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * 1e-3, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CascadeAxis_Step);

}  // namespace
