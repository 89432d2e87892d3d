// Tilted tools on a tri-dexel field (issue 24 section 2): the cost of a ball, a flat end and a bull-nose of the same
// diameter on the same five-axis-like moves, with the fast kernel (removal/cut.cpp, the bull-nose bracketed by exact
// flat-end sweeps, swept_tool.cpp) and the reference kernel (removal/cut_reference.cpp: the bull-nose solved by nested
// golden sections on every ray, as before issue 24). The moves: a contour of 60 straight sweeps round a 30 x 20 mm
// rectangle, 2 mm deep into a 40 x 30 x 12 mm block, the D10 tool tilted 50 deg outwards (NX's chamfer profile in
// APT_code.txt is of this kind, 49-65 deg). Arguments: tool (0 ball R5, 1 flat D10, 2 bull-nose D10 R1.6), kernel (0
// fast, 1 reference), spacing 1/n mm. Counters: ray evaluations (the kernel's ray_tests) and evaluations per second of
// CPU time. Figures: bench/README.md.
#include "removal/cut.hpp"
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <ctime>

namespace {

using namespace vmsim::removal;

const Box kBlock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(40, 30, 12)};

std::vector<SweptTool> contour(int kind) {
  Tool t;
  t.radius_mm = 5;
  t.corner_radius_mm = kind == 0 ? 5.0 : kind == 1 ? 0.0 : 1.6;
  t.length_mm = 40;
  const Eigen::Vector2d c(20, 15);
  std::vector<SweptTool> s;
  const int n = 60;
  auto point = [&](int k) {  // round the 30 x 20 rectangle's perimeter (100 mm), k of n
    double p = 100.0 * (k % n) / n;
    if (p < 30) return Eigen::Vector2d(5 + p, 5);
    p -= 30;
    if (p < 20) return Eigen::Vector2d(35, 5 + p);
    p -= 20;
    if (p < 30) return Eigen::Vector2d(35 - p, 25);
    p -= 30;
    return Eigen::Vector2d(5, 25 - p);
  };
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d a = point(k), b = point(k + 1), out = (0.5 * (a + b) - c).normalized();
    const double tilt = 50 * M_PI / 180;
    SweptTool w;
    w.tool = t;
    w.tip0 = Eigen::Vector3d(a.x(), a.y(), 10);
    w.d = Eigen::Vector3d(b.x() - a.x(), b.y() - a.y(), 0);
    w.axis = Eigen::Vector3d(std::sin(tilt) * out.x(), std::sin(tilt) * out.y(), std::cos(tilt));
    s.push_back(w);
  }
  return s;
}

double cpu_s() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

void BM_TiltedContour(benchmark::State& state) {
  const int kind = static_cast<int>(state.range(0));
  const bool reference = state.range(1) == 1;
  const double h = 1.0 / static_cast<double>(state.range(2));
  const std::vector<SweptTool> sweeps = contour(kind);
  double tests = 0, cpu = 0;
  for (auto _ : state) {
    state.PauseTiming();
    TriDexel f = make_tridexel(kBlock, h);
    for (DexelGrid* g : {&f.x, &f.y, &f.z}) fill_box(*g, kBlock);
    state.ResumeTiming();
    const double c0 = cpu_s();
    for (DexelGrid* g : {&f.x, &f.y, &f.z})
      tests += static_cast<double>((reference ? cut_reference(*g, sweeps) : cut(*g, sweeps)).ray_tests);
    cpu += cpu_s() - c0;
  }
  state.counters["evaluations"] = benchmark::Counter(tests / static_cast<double>(state.iterations()));
  state.counters["evals_per_cpu_s"] = benchmark::Counter(tests / cpu);
  state.counters["cpu_s"] = benchmark::Counter(cpu / static_cast<double>(state.iterations()));
}
BENCHMARK(BM_TiltedContour)
    ->ArgNames({"tool", "reference", "per_mm"})
    ->Args({0, 0, 4})
    ->Args({1, 0, 4})
    ->Args({2, 0, 4})
    ->Args({0, 1, 4})
    ->Args({2, 1, 4})
    ->Args({0, 0, 10})
    ->Args({2, 0, 10})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

}  // namespace
