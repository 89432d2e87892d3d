// Material removal throughput on the raster of ../shared/peers/peer_freecad_sim.py (the side-by-side comparison
// with FreeCAD's path simulator): a 100 x 100 mm area, zig-zag passes along X 0.5 mm apart, 21 points per pass
// 5 mm apart following z = 15 - 3 exp(-((x - 50)/15)^2), ball-end R5, stock 100 x 100 x 20.
// Counters: ray-tool evaluations per second (one thread), and the largest height error against the exact ball
// envelope of peer_envelope_grid.py (its formula, evaluated here at its 1 mm nodes, which lie on pass centres).
// Figures: bench/README.md.
#include "removal/fields.hpp"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <cmath>

namespace {

using namespace vmsim::removal;

double zdip(double x) { return 15.0 - 3.0 * std::exp(-((x - 50.0) / 15.0) * ((x - 50.0) / 15.0)); }

std::vector<SweptTool> raster(double step) {
  Tool t;
  t.radius_mm = 5;
  t.corner_radius_mm = 5;
  t.length_mm = 40;
  std::vector<SweptTool> out;
  const int ny = static_cast<int>(100 / step) + 1;
  for (int j = 0; j < ny; ++j) {
    const double y = j * step;
    for (int k = 0; k < 20; ++k) {
      const int a = (j % 2 == 0) ? k : 20 - k, b = (j % 2 == 0) ? k + 1 : 19 - k;
      SweptTool s;
      s.tool = t;
      s.tip0 = Eigen::Vector3d(5.0 * a, y, zdip(5.0 * a));
      s.d = Eigen::Vector3d(5.0 * b, y, zdip(5.0 * b)) - s.tip0;
      out.push_back(s);
    }
  }
  return out;
}

// peer_envelope_grid.py: along a pass, the envelope of the ball over the piecewise-linear tip path.
double envelope(double x) {
  auto ztip = [](double xx) {
    xx = std::min(std::max(xx, 0.0), 100.0);
    const int i = std::min(static_cast<int>(xx / 5), 19);
    const double t = (xx - 5.0 * i) / 5.0;
    return zdip(5.0 * i) * (1 - t) + zdip(5.0 * (i + 1)) * t;
  };
  double e = 1e300;
  for (int k = 0; k <= 400; ++k) {
    const double o = 5 - 10.0 * k / 400;
    e = std::min(e, ztip(x - o) + 5 - std::sqrt(std::max(25 - o * o, 0.0)));
  }
  return e;
}

void BM_ZmapBallRaster(benchmark::State& state) {
  const double h = 1.0 / static_cast<double>(state.range(0));  // spacing: 1/16 and 1/32 mm
  omp_set_num_threads(1);
  const std::vector<SweptTool> sw = raster(0.5);
  const Box stock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(100, 100, 20)};
  std::size_t tests = 0;
  double max_err = 0;
  for (auto _ : state) {
    state.PauseTiming();
    DexelGrid z = make_zmap(stock, h);
    fill_box(z, stock);
    state.ResumeTiming();
    tests = cut(z, sw).ray_tests;
    state.PauseTiming();
    max_err = 0;
    for (int xi = 2; xi <= 98; ++xi) {
      const double e = envelope(xi);
      for (int yi = 2; yi <= 98; ++yi)
        max_err = std::max(max_err, std::abs(z.top(static_cast<int>(std::lround(xi / h)), static_cast<int>(std::lround(yi / h))) - e));
    }
    state.ResumeTiming();
  }
  omp_set_num_threads(omp_get_num_procs());
  const double it = static_cast<double>(state.iterations());
  state.counters["ray_tests/s"] = benchmark::Counter(it * tests, benchmark::Counter::kIsRate);
  state.counters["max_err_um"] = max_err * 1e3;
  state.counters["sweeps"] = static_cast<double>(sw.size());
}
BENCHMARK(BM_ZmapBallRaster)->Arg(16)->Arg(32)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
