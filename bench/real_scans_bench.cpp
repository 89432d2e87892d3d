// Reading the real scans of ../shared/data/real/scans (issue 17): time per file through
// metrology::read_surface_file (what vmsim stats and compare call), points per second, and the process's peak
// resident set after the reads (run one file per process with --benchmark_filter to see each file's own peak).
// BM_GwyddionConvert runs Gwyddion 2.62's headless conversion of the same file, interleaved in the same run, as
// the peer's figure (a whole process: start-up included). Files that are absent are skipped. Figures: bench/README.md.
#include "metrology/surface_io.hpp"

#include <benchmark/benchmark.h>

#include <sys/resource.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;
const char* const kFiles[] = {"KautschukInfiniteFocus.x3p",        "sample-land.x3p",
                              "SurfaceTopography/x3p-2.x3p",       "SurfaceTopography/sur-3.sur",
                              "SurfaceTopography/bcrf-1.bcrf",     "SurfaceTopography/matrix-3.txt",
                              "SurfaceTopography/matrix-4.txt.gz", "SurfaceTopography/dektak-1.csv"};

fs::path real(int k) { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "scans" / kFiles[k]; }

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

void BM_ReadRealScan(benchmark::State& state) {
  const fs::path file = real(static_cast<int>(state.range(0)));
  state.SetLabel(kFiles[state.range(0)]);
  if (!fs::exists(file)) {
    state.SkipWithError((file.string() + " is absent").c_str());
    return;
  }
  std::size_t points = 0;
  for (auto _ : state) {
    const auto f = vmsim::metrology::read_surface_file(file);
    points = static_cast<std::size_t>(f.grid.z_mm.size());
    benchmark::DoNotOptimize(f.grid.z_mm.data());
  }
  state.counters["points"] = static_cast<double>(points);
  state.counters["points_per_s"] =
      benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["file_MB"] = static_cast<double>(fs::file_size(file)) / 1e6;
  state.counters["peak_rss_MB"] = peak_rss_mb();
}

void BM_GwyddionConvert(benchmark::State& state) {
  const fs::path file = real(static_cast<int>(state.range(0)));
  state.SetLabel(kFiles[state.range(0)]);
  if (!fs::exists(file) || std::system("command -v gwyddion > /dev/null 2>&1") != 0) {
    state.SkipWithError("file absent or Gwyddion not installed");
    return;
  }
  const fs::path out = fs::temp_directory_path() / ("vmsim_bench_gwy_" + std::to_string(::getpid()) + ".gwy");
  const std::string cmd = "gwyddion --convert-to-gwy='" + out.string() + "' '" + file.string() + "' > /dev/null 2>&1";
  for (auto _ : state)
    if (std::system(cmd.c_str()) != 0) {
      state.SkipWithError("Gwyddion cannot read the file");
      break;
    }
  fs::remove(out);
}

void files(benchmark::internal::Benchmark* b) {
  for (int k = 0; k < static_cast<int>(std::size(kFiles)); ++k) b->Arg(k);
}

}  // namespace

BENCHMARK(BM_ReadRealScan)->Apply(files)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_GwyddionConvert)->Apply(files)->Unit(benchmark::kMillisecond)->UseRealTime();
