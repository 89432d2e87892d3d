// Contour-error throughput: actual samples per second through motion::contour_error (foot-point search, exact
// segment distance, sign), on long synthetic paths sampled as the interpolator samples them (Te = 1 ms).
// Target: >= 10 M samples/s on one core. Figures: bench/README.md.
#include "motion/contour.hpp"

#include <Eigen/Core>
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>

namespace {

using namespace vmsim::motion;

struct Case {
  Eigen::MatrixXd command, actual;
};

// The predictive-compensation paper's starfish contour (five lobes, r = 40 + 8 sin 5 theta mm) at 3 m/min (50 um per
// sample), laps repeated to `samples`. The actual lags 12.4 samples (0.62 mm) with a 0-6 um lateral error varying along
// the path: the lag is ten times the step, so the search has real work to do.
Case starfish(Eigen::Index samples) {
  Case c;
  c.command.resize(samples, 3);
  c.actual.resize(samples, 3);
  const double step_rad = 0.05 / 40.0;
  auto at = [&](double k, double lateral) {
    const double th = step_rad * k;
    const double r = 40.0 + 8.0 * std::sin(5.0 * th) + lateral;
    return Eigen::RowVector3d(r * std::cos(th), r * std::sin(th), 0.02 * std::sin(0.5 * th));
  };
  for (Eigen::Index k = 0; k < samples; ++k) {
    c.command.row(k) = at(static_cast<double>(k), 0.0);
    const double kk = std::max(0.0, k - 12.4);
    c.actual.row(k) = at(kk, 0.006 * std::sin(0.003 * kk));
  }
  return c;
}

// Zigzag raster, 0.25 mm stepover, 40 mm passes at 10 m/min (0.167 mm per sample), the actual lagging 1.5 mm
// (nine samples) with a 20 um lateral error: the plane-cylinder part's finishing pattern at its fast feed.
Case raster(Eigen::Index samples) {
  Case c;
  c.command.resize(samples, 3);
  c.actual.resize(samples, 3);
  const double h = 10000.0 / 60.0 / 1000.0, len = 40.0;
  const Eigen::Index per_pass = static_cast<Eigen::Index>(len / h) + 2;
  auto at = [&](double k) {
    const double pass = std::floor(k / per_pass), i = k - pass * per_pass;
    const double x = std::min(i * h, len);
    const double y = 0.25 * (pass + std::max(0.0, i * h - len) / (2 * h));  // a short connector at the end
    return Eigen::RowVector3d(static_cast<long>(pass) % 2 == 0 ? x : len - x, y, 0.0);
  };
  for (Eigen::Index k = 0; k < samples; ++k) {
    c.command.row(k) = at(static_cast<double>(k));
    c.actual.row(k) = at(std::max(0.0, k - 9.0)) + Eigen::RowVector3d(0, 0.02, 0);
  }
  return c;
}

void run(benchmark::State& state, const Case& c, const ContourOptions& opt) {
  double mse = 0.0;
  for (auto _ : state) {
    ContourError ce = contour_error(c.command, c.actual, opt);
    mse = ce.mse_um2;
    benchmark::DoNotOptimize(ce.signed_mm.data());
  }
  state.counters["samples/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * c.actual.rows(), benchmark::Counter::kIsRate);
  state.counters["mse_um2"] = mse;
}

void BM_Contour_Starfish(benchmark::State& state) {
  static const Case c = starfish(state.range(0));
  ContourOptions opt;
  opt.plane_normal = Eigen::Vector3d::UnitZ();
  run(state, c, opt);
}
BENCHMARK(BM_Contour_Starfish)->Arg(4'000'000)->Unit(benchmark::kMillisecond);

void BM_Contour_StarfishPrincipalNormal(benchmark::State& state) {
  static const Case c = starfish(state.range(0));
  run(state, c, {});
}
BENCHMARK(BM_Contour_StarfishPrincipalNormal)->Arg(4'000'000)->Unit(benchmark::kMillisecond);

void BM_Contour_Raster(benchmark::State& state) {
  static const Case c = raster(state.range(0));
  ContourOptions opt;
  opt.plane_normal = Eigen::Vector3d::UnitZ();
  run(state, c, opt);
}
BENCHMARK(BM_Contour_Raster)->Arg(4'000'000)->Unit(benchmark::kMillisecond);

}  // namespace
