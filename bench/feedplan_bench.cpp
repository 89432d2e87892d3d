// Feed planning (Chen et al. 2016, drives/feedplan): size and solve time of the linear program on the squared feed, and
// the cost growth of the windowed plan with the path length. The path: the butterfly curve (parts/feedplan) sampled by
// parameter with arc-length correction every 0.05 mm, traversed as many times as the sample count needs (the
// samples tiled end to end, arc length continued), Chen et al. 2016 section 4's limits (T 4 ms, chord 0.5 um, contour
// error 20 um with its PID servo, 50 mm/s, 200 mm/s^2) and the jerk of parts/feedplan/chen2016_machine.toml (5000
// mm/s^3). Targets (issue 10): 20 000 samples in <= 1 s; the windowed cost linear in the path length. Figures:
// bench/README.md.
#include "motion/nurbs.hpp"
#include "methods/feedplan.hpp"
#include "methods/feedplan_servo.hpp"

#include <benchmark/benchmark.h>

#include <filesystem>

namespace {

using namespace vmsim;
using Index = Eigen::Index;

const std::filesystem::path kParts = std::filesystem::path(VMSIM_SOURCE_DIR) / "parts/feedplan";

const methods::PathSamples& butterfly() {
  static const methods::PathSamples ps = methods::sample_nurbs(
      motion::read_nurbs_csv(kParts / "butterfly_nurbs_control_points.csv", kParts / "butterfly_nurbs_knots.csv", 3),
      0.05);
  return ps;
}

// n samples: the butterfly's samples repeated (each lap's first sample dropped: it is the previous lap's last).
methods::PathSamples tiled(Index n) {
  const methods::PathSamples& b = butterfly();
  methods::PathSamples out;
  out.ds = b.ds;
  out.s.resize(n);
  out.u.resize(n);
  for (Eigen::MatrixXd* m : {&out.p, &out.t, &out.k, &out.dk, &out.t_abs_max, &out.k_abs_max}) m->resize(n, 3);
  out.kappa_max.resize(n);
  const Index lap = b.size() - 1;
  for (Index i = 0; i < n; ++i) {
    const Index j = i < b.size() ? i : 1 + (i - b.size()) % lap;
    out.s[i] = i * b.ds;
    out.u[i] = b.u[j];
    out.p.row(i) = b.p.row(j);
    out.t.row(i) = b.t.row(j);
    out.k.row(i) = b.k.row(j);
    out.dk.row(i) = b.dk.row(j);
    out.t_abs_max.row(i) = b.t_abs_max.row(j);
    out.k_abs_max.row(i) = b.k_abs_max.row(j);
    out.kappa_max[i] = b.kappa_max[j];
  }
  return out;
}

const methods::ContourErrorModel& model() {
  static const methods::ContourErrorModel m(
      {methods::frequency_response(methods::pid_servo_transfer_function(methods::chen2016_pid_x())),
       methods::frequency_response(methods::pid_servo_transfer_function(methods::chen2016_pid_y()))});
  return m;
}

methods::FeedPlanOptions options(bool jerk) {
  methods::FeedPlanOptions o;
  o.contour_model = &model();
  o.limits.period_s = 0.004;
  o.limits.chord_error_mm = 0.0005;
  o.limits.contour_error_mm = 0.020;
  o.limits.max_feed_mm_per_s = 50;
  o.limits.axis_velocity.setConstant(50);
  o.limits.axis_acceleration.setConstant(200);
  if (jerk) o.limits.axis_jerk.setConstant(5000);
  return o;
}

void report(benchmark::State& state, const methods::FeedPlan& p) {
  state.counters["samples"] = static_cast<double>(p.s.size());
  state.counters["lp_cols"] = static_cast<double>(p.stats.lp_columns_max);
  state.counters["lp_rows"] = static_cast<double>(p.stats.lp_rows_max);
  state.counters["lp_nnz"] = static_cast<double>(p.stats.lp_nonzeros_max);
  state.counters["windows"] = p.stats.windows;
  state.counters["solves"] = p.stats.lp_solves;
  state.counters["clp_s"] = p.stats.lp_seconds;
  state.counters["plan_s"] = p.stats.total_seconds;
  state.counters["us_per_sample"] = 1e6 * p.stats.total_seconds / static_cast<double>(p.s.size());
}

// One LP over the whole path (window = every sample): Chen et al.'s formulation as one Clp problem.
void BM_FeedPlanOneLp(benchmark::State& state) {
  const methods::PathSamples ps = tiled(state.range(0));
  methods::FeedPlanOptions o = options(state.range(1) != 0);
  o.window_samples = static_cast<int>(ps.size()) + 1;
  methods::FeedPlan p;
  for (auto _ : state) {
    p = methods::plan_feed(ps, o);
    benchmark::DoNotOptimize(p.feed.data());
  }
  report(state, p);
}
BENCHMARK(BM_FeedPlanOneLp)
    ->Args({20000, 0})
    ->Args({20000, 1})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3);

// Overlapping windows of 4000 samples (the default), 20 000 to 200 000 samples.
void BM_FeedPlanWindowed(benchmark::State& state) {
  const methods::PathSamples ps = tiled(state.range(0));
  const methods::FeedPlanOptions o = options(state.range(1) != 0);
  methods::FeedPlan p;
  for (auto _ : state) {
    p = methods::plan_feed(ps, o);
    benchmark::DoNotOptimize(p.feed.data());
  }
  report(state, p);
}
BENCHMARK(BM_FeedPlanWindowed)
    ->ArgsProduct({{20000, 50000, 100000, 200000}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(2);

}  // namespace
