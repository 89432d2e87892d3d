// The CPU of each result file `vmsim run` writes for a z-map job (issue 21: the `write` stage), writer by writer, on
// the grids of a real run: set VMSIM_OUTPUTS_BENCH_DIR to the output directory of `vmsim run
// bench/flower_mold/job.toml` (its surface.csv, reference.csv and deviation.csv are read back bit for bit). Without
// it, a 572 x 572 scalloped grid of the same size stands in. Process CPU (every thread) per write; each file is
// written to a scratch directory through the same function the run calls. Figures: bench/README.md.
#include "core/stl.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/x3p.hpp"
#include "removal/surface.hpp"
#include "render/mesh_io.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>

namespace {

using namespace vmsim;
namespace fs = std::filesystem;

struct OutputsData {
  core::HeightGrid surface, reference, deviation;
  core::TriangleMesh mesh;
  double bottom_z_mm = -10.0;
  fs::path dir;
};

core::HeightGrid scalloped_grid(double shift) {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.1;
  g.z_mm.resize(572, 572);
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i)
      g.z_mm(j, i) = -3 + 2 * std::sin(g.x(i) / 9.0) * std::cos(g.y(j) / 7.0) + 0.004 * std::cos(g.y(j) / 0.04) + shift;
  return g;
}

const OutputsData& outputs_data() {
  static const OutputsData d = [] {
    OutputsData r;
    if (const char* in = std::getenv("VMSIM_OUTPUTS_BENCH_DIR")) {
      r.surface = metrology::read_height_csv(fs::path(in) / "surface.csv");
      r.reference = metrology::read_height_csv(fs::path(in) / "reference.csv");
      r.deviation = metrology::read_height_csv(fs::path(in) / "deviation.csv");
    } else {
      r.surface = scalloped_grid(0), r.reference = scalloped_grid(-1e-3), r.deviation = scalloped_grid(-3);
    }
    r.mesh = removal::heightfield_mesh(r.surface, r.bottom_z_mm, &r.deviation);
    r.dir = fs::temp_directory_path() / "vmsim_outputs_bench";
    fs::create_directories(r.dir);
    return r;
  }();
  return d;
}

void BM_PartMesh(benchmark::State& state) {
  const OutputsData& d = outputs_data();
  for (auto _ : state) {
    core::TriangleMesh m = removal::heightfield_mesh(d.surface, d.bottom_z_mm, &d.deviation);
    benchmark::DoNotOptimize(m.triangles.data());
  }
  state.counters["triangles"] = static_cast<double>(d.mesh.triangles.rows());
}

void BM_Stl(benchmark::State& state) {
  const OutputsData& d = outputs_data();
  for (auto _ : state) core::write_stl_binary(d.dir / "part.stl", d.mesh);
  state.counters["bytes"] = static_cast<double>(fs::file_size(d.dir / "part.stl"));
}

void BM_Vtp(benchmark::State& state) {
  const OutputsData& d = outputs_data();
  for (auto _ : state) render::write_vtp(d.dir / "part.vtp", d.mesh, static_cast<int>(state.range(0)));
  state.counters["bytes"] = static_cast<double>(fs::file_size(d.dir / "part.vtp"));
}

void BM_HeightCsv(benchmark::State& state) {
  const OutputsData& d = outputs_data();
  for (auto _ : state) metrology::write_height_csv(d.dir / "surface.csv", d.surface);
  state.counters["bytes"] = static_cast<double>(fs::file_size(d.dir / "surface.csv"));
}

void BM_Npy(benchmark::State& state) {
  const OutputsData& d = outputs_data();
  for (auto _ : state) metrology::write_height_npy(d.dir / "surface.npy", d.surface);
  state.counters["bytes"] = static_cast<double>(fs::file_size(d.dir / "surface.npy"));
}

void BM_X3p(benchmark::State& state) {
  const OutputsData& d = outputs_data();
  metrology::X3pWriteOptions o;
  o.date = "2026-11-27T00:00:00+00:00";
  for (auto _ : state) metrology::write_x3p(d.dir / "surface.x3p", d.surface, o);
  state.counters["bytes"] = static_cast<double>(fs::file_size(d.dir / "surface.x3p"));
}

BENCHMARK(BM_PartMesh)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_Stl)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_Vtp)->Arg(1)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_HeightCsv)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_Npy)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_X3p)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

}  // namespace
