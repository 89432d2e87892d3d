// Interpolator throughput: setpoints and blocks per second, and simulated seconds per wall second (x real time),
// on LinuxCNC's 3D_Chips.ngc (4 681 short G1 moves, ../shared) and on the plane-cylinder reference program.
// Target (issue 2): >= 1000x real time at Te = 1 ms on one core. Figures: bench/README.md.
#include "program/gcode.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"

#include <benchmark/benchmark.h>

#include <filesystem>

namespace {

using namespace vmsim::core;
using namespace vmsim::motion;
using namespace vmsim::program;

const std::filesystem::path kShared = VMSIM_SHARED_DIR;
const std::filesystem::path kSource = VMSIM_SOURCE_DIR;

void run_interp(benchmark::State& state, const ToolPath& tp, const Machine& m) {
  InterpOptions opt;  // Te 1 ms, tolerance 20 um
  double cycle = 0.0;
  Eigen::Index samples = 0;
  for (auto _ : state) {
    InterpResult r = interpolate(tp, m, opt);
    cycle = r.stats.cycle_time_s;
    samples = r.setpoints.samples();
    benchmark::DoNotOptimize(r.setpoints.position.data());
  }
  const double it = static_cast<double>(state.iterations());
  state.counters["setpoints/s"] = benchmark::Counter(it * samples, benchmark::Counter::kIsRate);
  state.counters["blocks/s"] = benchmark::Counter(it * tp.moves.size(), benchmark::Counter::kIsRate);
  state.counters["x_real_time"] = benchmark::Counter(it * cycle, benchmark::Counter::kIsRate);
  state.counters["cycle_s"] = cycle;
}

void BM_Interp_3DChips(benchmark::State& state) {
  const auto prog = kShared / "data/gcode/programs/3D_Chips.ngc";
  if (!std::filesystem::exists(prog)) {
    state.SkipWithError("../shared/data is absent: 3D_Chips.ngc not available");
    return;
  }
  const Machine m = load_machine(kSource / "parts/machines/mikron_ucp710.toml");
  GcodeOptions g;
  g.tool_table = kShared / "data/gcode/tooltables/tool_common.tbl";
  const ToolPath tp = toolpath_in_axis_space(read_gcode(prog, g), m);
  run_interp(state, tp, m);
}
BENCHMARK(BM_Interp_3DChips)->Unit(benchmark::kMillisecond);

void BM_Interp_PlaneCylinderFast(benchmark::State& state) {
  const Job job = load_job(kSource / "parts/plane_cylinder/job_fast.toml");
  ProgramOptions po;
  po.tool_table = job.tool_table_file;
  const ToolPath tp = toolpath_in_axis_space(read_program(job.program_file, po), job.machine);
  run_interp(state, tp, job.machine);
}
BENCHMARK(BM_Interp_PlaneCylinderFast)->Unit(benchmark::kMillisecond);

void BM_Interp_PlaneCylinderReference(benchmark::State& state) {
  const Job job = load_job(kSource / "parts/plane_cylinder/job_reference.toml");
  ProgramOptions po;
  po.tool_table = job.tool_table_file;
  const ToolPath tp = toolpath_in_axis_space(read_program(job.program_file, po), job.machine);
  run_interp(state, tp, job.machine);
}
BENCHMARK(BM_Interp_PlaneCylinderReference)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_ReadGcode_3DChips(benchmark::State& state) {
  const auto prog = kShared / "data/gcode/programs/3D_Chips.ngc";
  if (!std::filesystem::exists(prog)) {
    state.SkipWithError("../shared/data is absent: 3D_Chips.ngc not available");
    return;
  }
  GcodeOptions g;
  g.tool_table = kShared / "data/gcode/tooltables/tool_common.tbl";
  std::size_t lines = 0;
  for (auto _ : state) {
    GcodeResult r = interpret_gcode(prog, g);
    lines = r.canon.size();
    benchmark::DoNotOptimize(r.path.moves.data());
  }
  state.counters["canon_calls/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * lines, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ReadGcode_3DChips)->Unit(benchmark::kMillisecond);

}  // namespace
