// Metrology on a 2000 x 2000 scan (the issue: "reading, registering and comparing a 2000 x 2000 scan: time and
// memory"): a STIL-style scan of a machined-looking surface, 10 x 10 mm at 5 um, placed by a known rigid transform
// with noise, spikes and dropouts, against a 2000 x 2000 prediction. Each stage alone, then the whole comparison
// as vmsim compare runs it (less the pictures). Peak memory: the process's maximum resident set (a counter);
// run one benchmark per process (--benchmark_filter) to see each stage's own peak. Figures: bench/README.md.
#include "metrology/areal.hpp"
#include "metrology/filter.hpp"
#include "metrology/form.hpp"
#include "metrology/marks.hpp"
#include "metrology/register.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <benchmark/benchmark.h>

#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>

namespace {

using namespace vmsim;
namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;
constexpr int kN = 2000;
constexpr double kStep = 0.005;

// Scallops of a 0.25 mm stepover (ridges along x), a 2 mm wave, a ball-end groove and an 8 um mark.
double part(double x, double y) {
  double z = 0.004 * std::cos(2 * kPi * y / 0.25) + 0.01 * std::sin(2 * kPi * x / 2.0) * std::cos(2 * kPi * y / 3.0) +
             0.001 * x - 0.0005 * y;
  z -= 0.03 * std::exp(-std::pow((x - 7.0) / 0.4, 2));
  return z;
}

struct Data {
  core::HeightGrid pred, scan;
  metrology::RigidTransform truth;
  fs::path scan_file, pred_file;
};

const Data& data() {
  static const Data d = [] {
    Data r;
    r.pred.dx_mm = r.pred.dy_mm = kStep;
    r.pred.z_mm.resize(kN, kN);
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) r.pred.z_mm(j, i) = part(r.pred.x(i), r.pred.y(j));
    r.truth = metrology::RigidTransform::from_xyz_rxyz(0.05, -0.03, 0.2, 1e-3, -1.5e-3, 2e-3);
    // The scan in its own frame: the surface point above each scan node after the inverse placement, plus the
    // 8 um mark the prediction does not have, noise, spikes and dropouts.
    const metrology::RigidTransform inv = r.truth.inverse();
    r.scan = r.pred;
    r.scan.x0_mm = r.scan.y0_mm = 0.1;
    std::mt19937_64 rng(1);
    std::normal_distribution<double> noise(0, 0.0002);
    std::uniform_real_distribution<double> u(0, 1);
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        const double xs = r.scan.x(i), ys = r.scan.y(j);
        Eigen::Vector3d P = r.truth.apply({xs, ys, 0});
        for (int it = 0; it < 6; ++it) {
          P.z() = part(P.x(), P.y()) -
                  0.008 * std::exp(-std::pow((P.y() - 5.0) / 0.1, 2) - std::pow((P.x() - 4.0) / 1.5, 2));
          const Eigen::Vector3d p = inv.apply(P);
          P.head<2>() += r.truth.R.topLeftCorner<2, 2>() * Eigen::Vector2d(xs - p.x(), ys - p.y());
        }
        double z = inv.apply(P).z() + noise(rng);
        const double v = u(rng);
        if (v < 0.0005) z += 0.1;
        if (v > 0.998) z = NAN;
        r.scan.z_mm(j, i) = z;
      }
    const fs::path dir = fs::temp_directory_path() / ("vmsim_metrology_bench_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    r.scan_file = dir / "scan.x3p";
    r.pred_file = dir / "predicted.x3p";
    metrology::write_x3p(r.scan_file, r.scan);
    metrology::write_x3p(r.pred_file, r.pred);
    static const struct Cleanup {
      fs::path dir;
      ~Cleanup() {
        std::error_code ec;
        fs::remove_all(dir, ec);
      }
    } cleanup{dir};
    return r;
  }();
  return d;
}

void peak_rss(benchmark::State& state) {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  state.counters["peak_rss_MB"] = static_cast<double>(ru.ru_maxrss) / 1024.0;
  state.counters["points"] = static_cast<double>(kN) * kN;
}

void BM_ReadX3p(benchmark::State& state) {
  const Data& d = data();
  for (auto _ : state) benchmark::DoNotOptimize(metrology::read_x3p(d.scan_file));
  state.counters["file_MB"] = static_cast<double>(fs::file_size(d.scan_file)) / 1e6;
  peak_rss(state);
}

void BM_WriteX3p(benchmark::State& state) {
  const Data& d = data();
  const fs::path p = d.scan_file.parent_path() / "written.x3p";
  for (auto _ : state) metrology::write_x3p(p, d.scan);
  peak_rss(state);
}

void BM_MaskOutliers(benchmark::State& state) {
  const Data& d = data();
  std::size_t masked = 0;
  for (auto _ : state) {
    core::HeightGrid g = d.scan;
    masked = metrology::mask_outliers(g).masked;
  }
  state.counters["masked"] = static_cast<double>(masked);
  peak_rss(state);
}

void BM_Register(benchmark::State& state) {
  const Data& d = data();
  metrology::RegistrationResult r;
  for (auto _ : state) r = metrology::register_scan(d.scan, d.pred);
  double worst = 0;
  for (double x : {d.scan.x0_mm, d.scan.x(kN - 1)})
    for (double y : {d.scan.y0_mm, d.scan.y(kN - 1)})
      worst = std::max(worst, (r.transform.apply({x, y, 0}) - d.truth.apply({x, y, 0})).norm());
  state.counters["error_um"] = worst * 1e3;
  state.counters["error_rad"] = Eigen::AngleAxisd(r.transform.R * d.truth.R.transpose()).angle();
  state.counters["iterations"] = r.iterations;
  peak_rss(state);
}

void BM_Resample(benchmark::State& state) {
  const Data& d = data();
  for (auto _ : state) benchmark::DoNotOptimize(metrology::resample_scan(d.scan, d.truth, d.pred));
  peak_rss(state);
}

void BM_ArealParameters(benchmark::State& state) {
  const Data& d = data();
  for (auto _ : state) benchmark::DoNotOptimize(metrology::areal_parameters(metrology::remove_form(d.pred, 1)));
  peak_rss(state);
}

void BM_GaussianFilter(benchmark::State& state) {
  const Data& d = data();
  for (auto _ : state) benchmark::DoNotOptimize(metrology::gaussian_mean_surface(d.pred, 0.25));
  peak_rss(state);
}

// vmsim compare without the pictures and the files: read both X3P, mask spikes, register, resample, deviation,
// marks, areal parameters of both on the common area.
void BM_CompareEndToEnd(benchmark::State& state) {
  const Data& d = data();
  std::size_t marks = 0;
  for (auto _ : state) {
    core::HeightGrid scan = metrology::read_x3p(d.scan_file).grid;
    const core::HeightGrid pred = metrology::read_x3p(d.pred_file).grid;
    metrology::mask_outliers(scan);
    const auto reg = metrology::register_scan(scan, pred);
    const core::HeightGrid on = metrology::resample_scan(scan, reg.transform, pred);
    const core::HeightGrid dev = metrology::deviation(on, pred);
    marks = metrology::find_marks(dev, 0.001, 10, metrology::lay_of(pred).direction_rad, 9).size();
    core::HeightGrid mc = on, pc = pred;
    for (Eigen::Index k = 0; k < mc.z_mm.size(); ++k)
      if (!std::isfinite(mc.z_mm.data()[k])) pc.z_mm.data()[k] = NAN;
    benchmark::DoNotOptimize(metrology::areal_parameters(metrology::remove_form(mc, 1)));
    benchmark::DoNotOptimize(metrology::areal_parameters(metrology::remove_form(pc, 1)));
  }
  state.counters["marks"] = static_cast<double>(marks);
  peak_rss(state);
}

BENCHMARK(BM_ReadX3p)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WriteX3p)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MaskOutliers)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Register)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Resample)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GaussianFilter)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ArealParameters)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CompareEndToEnd)->Unit(benchmark::kMillisecond);

}  // namespace
