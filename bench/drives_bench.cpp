// Drive simulation throughput: simulated seconds per wall second (x real time) of simulate_axes on the Mikron
// UCP 710's five cascade drives (current loop 16 kHz, velocity loop 8 kHz, position loop 1 kHz), one thread, on
// the interpolator's setpoints for the plane-cylinder part's 10 m/min pass. Target (drives issue): >= 100x real
// time for 5 axes on one core. Issue 21: the same drives over flower_mold's 3.72 M setpoints in the blocks a run
// uses (process CPU time), and over a synthetic profile that moves all five axes. Figures: bench/README.md.
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/cascade_batch.hpp"
#include "drives/simulate.hpp"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <cmath>
#include <filesystem>

namespace {

using namespace vmsim;

const std::filesystem::path kSource = VMSIM_SOURCE_DIR;
const std::filesystem::path kShared = VMSIM_SHARED_DIR;

struct Stream {
  core::Job job;
  core::Setpoints setpoints;
};

Stream interpolated(const std::filesystem::path& job_file) {
  Stream out{core::load_job(job_file), {}};
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
}

const Stream& plane_cylinder_fast() {
  static const Stream s = interpolated(kSource / "parts/plane_cylinder/job_fast.toml");
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

// The same axis in state.range(0) copies stepped together by a CascadeBatch (each its own phase of the sine): the
// cost of one Te per axis when the core overlaps the axes' chains.
void BM_CascadeBatch_Step(benchmark::State& state) {
  const core::Machine& m = plane_cylinder_fast().job.machine;
  const int lanes = static_cast<int>(state.range(0));
  std::vector<drives::CascadeAxis> axes(static_cast<std::size_t>(lanes),
                                        drives::CascadeAxis(*m.axes[0].drive, 1e-3, m.axes[0].kind));
  std::vector<drives::CascadeAxis*> ptrs;
  for (auto& a : axes) {
    a.reset(0.0);
    ptrs.push_back(&a);
  }
  drives::CascadeBatch batch(ptrs, false);
  drives::AxisCommand c[drives::CascadeBatch::kMaxLanes];
  drives::AxisSample out[drives::CascadeBatch::kMaxLanes];
  long long k = 0;
  for (auto _ : state) {
    const double t = static_cast<double>(k++) * 1e-3;
    for (int l = 0; l < lanes; ++l) {
      c[l].position = 10.0 * std::sin(t + l);
      c[l].velocity = 10.0 * std::cos(t + l);
    }
    batch.step(c, out);
    benchmark::DoNotOptimize(out[0]);
  }
  state.counters["ns_per_axis_te"] = benchmark::Counter(static_cast<double>(state.iterations()) * lanes * 1e-9,
                                                        benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CascadeBatch_Step)->Arg(1)->Arg(2)->Arg(3)->Arg(5);

// The drives as a run uses them: BlockSimulation in blocks of 65 536 rows (sim/motion_stream's default), every block
// dropped once made. Process CPU time (all threads), one iteration: a whole program.
void run_blocks(benchmark::State& state, const Stream& s, int threads) {
  omp_set_num_threads(threads);
  double simulated = 0.0;
  long long inner_steps = 0;
  for (auto _ : state) {
    drives::BlockSimulation sim(s.setpoints, s.job.machine);
    while (!sim.done()) {
      const drives::AxisResponse r = sim.next(65536);
      benchmark::DoNotOptimize(r.position.data());
    }
    simulated = static_cast<double>(sim.rows() - 1) * s.setpoints.period_s;
    inner_steps = 0;
    for (const auto& ax : s.job.machine.axes)
      if (ax.drive) inner_steps += static_cast<long long>(std::llround(simulated / ax.drive->current_period_s));
  }
  const double it = static_cast<double>(state.iterations());
  state.counters["threads"] = threads;
  state.counters["simulated_s"] = simulated;
  state.counters["ns_per_current_step"] = benchmark::Counter(it * static_cast<double>(inner_steps) * 1e-9,
                                                             benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// CAMotics' flower_mold.nc on the Mikron (bench/flower_mold/job.toml, program from ../shared): 3.72 M setpoints;
// X Y Z move, A and C hold.
const Stream* flower_mold() {
  static const Stream* s = [] {
    const std::filesystem::path program = kShared / "data/real/cam/flower_mold.nc";
    return std::filesystem::exists(program) ? new Stream(interpolated(kSource / "bench/flower_mold/job.toml"))
                                            : nullptr;
  }();
  return s;
}

void BM_Drives_FlowerMold_Blocks(benchmark::State& state) {
  const Stream* s = flower_mold();
  if (!s) {
    state.SkipWithError("../shared/data/real/cam/flower_mold.nc is absent");
    return;
  }
  run_blocks(state, *s, static_cast<int>(state.range(0)));
}
BENCHMARK(BM_Drives_FlowerMold_Blocks)
    ->Arg(1)
    ->Arg(2)
    ->Iterations(1)
    ->MeasureProcessCPUTime()
    ->UseRealTime()
    ->Unit(benchmark::kSecond);

// All five Mikron axes moving at once (no axis ever at rest): 120 s of sines through the friction band with
// reversals every few seconds, A tilting through +-30 deg (its gravity varies), C turning. The setpoints are not
// jerk-limited; the accelerations stay within the drives' current limits.
const Stream& five_axes_moving() {
  static const Stream s = [] {
    Stream out{core::load_job(kSource / "parts/plane_cylinder/job_fast.toml"), {}};
    out.job.machine = core::load_machine(kSource / "parts/machines/mikron_ucp710.toml");
    const Eigen::Index n = 120000;
    out.setpoints.period_s = 1e-3;
    for (const auto& ax : out.job.machine.axes) out.setpoints.axis_names.push_back(ax.name);
    out.setpoints.position.resize(n, 5);
    const double amp[5] = {50.0, 40.0, 20.0, 0.5, 1.5}, f_hz[5] = {0.13, 0.21, 0.17, 0.05, 0.07};
    for (Eigen::Index k = 0; k < n; ++k)
      for (int a = 0; a < 5; ++a)
        out.setpoints.position(k, a) =
            amp[a] * std::sin(2.0 * 3.141592653589793 * f_hz[a] * static_cast<double>(k) * 1e-3);
    out.setpoints.path_speed_mm_per_s.setZero(n);
    out.setpoints.path_length_mm.setZero(n);
    out.setpoints.move_index.setZero(n);
    return out;
  }();
  return s;
}

void BM_Drives_FiveAxesMoving_Blocks(benchmark::State& state) {
  run_blocks(state, five_axes_moving(), static_cast<int>(state.range(0)));
}
BENCHMARK(BM_Drives_FiveAxesMoving_Blocks)
    ->Arg(1)
    ->Arg(2)
    ->Iterations(3)
    ->MeasureProcessCPUTime()
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
