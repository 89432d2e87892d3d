// Material removal throughput on the raster of ../shared/peers/peer_freecad_sim.py (the side-by-side comparison
// with FreeCAD's path simulator): the peer's whole program, move for move. From (0,0,30): G1 plunge to
// z = zdip(0) at (0,0); 201 zig-zag passes along X, 0.5 mm apart in Y (even passes x 0 -> 100, odd 100 -> 0), each
// 20 moves through 21 points 5 mm apart on z = zdip(x) = 15 - 3 exp(-((x - 50)/15)^2); a stepover move in Y at
// constant z between passes; the final G0 Z30 retract (FreeCAD applies G0 like G1). Ball end R5 (the peer's tool is
// 45 mm long from the tip), stock 100 x 100 x 20. Coordinates are the exact values (the peer's G-code rounds them
// to 0.1 um), as in peer_envelope_grid.py.
//
// Arguments: spacing as 1/n mm (16, 32), the OpenMP thread count (1, 2) and the kernel: 0 cut() (the AVX2 build
// where the CPU has it), 1 cut_reference() (the kernel before issue 21's tile bounds and fused rows: the "before" of
// one interleaved run), 2 cut() in its generic build.
// Counters: ray-tool evaluations per second (all threads; per thread), the shares of the evaluations settled by a
// tile's bound, by the ray's bound and by the exact cut without change, and of those that cut (cut() only), the height
// error against the exact ball envelope of peer_envelope_grid.py (its formula, evaluated here at the 1 mm nodes x, y in
// [2, 98], which lie on pass centres), the z-map's memory (DexelGrid::memory_bytes per dexel) and the stock set-up time
// (make_zmap + fill_box, not in the timed region). The timed region is cut() alone. VMSIM_REMOVAL_HEIGHTS=prefix writes
// the z-map's heights at x, y = 1..99 mm to prefix_<n>_t<threads>.xyz ("x y z" lines, the layout of the peer script's
// .heights.xyz) for comparison with peer_envelope_grid.py's ref.xyz. Figures: bench/README.md.
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "removal/cut_internal.hpp"
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "sim/chain.hpp"
#include "sim/pipeline.hpp"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>

namespace {

using namespace vmsim::removal;

double zdip(double x) { return 15.0 - 3.0 * std::exp(-((x - 50.0) / 15.0) * ((x - 50.0) / 15.0)); }

std::vector<SweptTool> raster(double step) {
  Tool t;
  t.radius_mm = 5;
  t.corner_radius_mm = 5;
  t.length_mm = 45;
  // Tip positions in program order (peer_freecad_sim.py: G0 Z30, G0 X0 Y0, G1 Z zdip(0), passes, G0 Z30).
  std::vector<Eigen::Vector3d> p{{0, 0, 30}, {0, 0, zdip(0)}};
  const int ny = static_cast<int>(std::lround(100 / step)) + 1;
  for (int j = 0; j < ny; ++j) {
    const double y = j * step;
    for (int k = 0; k <= 20; ++k) {
      if (j == 0 && k == 0) continue;  // the plunge's end; for j > 0, k = 0 is the stepover move
      const double x = 5.0 * ((j % 2 == 0) ? k : 20 - k);
      p.emplace_back(x, y, zdip(x));
    }
  }
  p.emplace_back(p.back().x(), p.back().y(), 30.0);
  std::vector<SweptTool> out;
  for (std::size_t k = 1; k < p.size(); ++k) {
    if ((p[k] - p[k - 1]).norm() == 0) continue;
    SweptTool s;
    s.tool = t;
    s.tip0 = p[k - 1];
    s.d = p[k] - p[k - 1];
    out.push_back(s);
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

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void BM_ZmapBallRaster(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const double h = 1.0 / n;  // spacing: 1/16 and 1/32 mm
  const int threads = static_cast<int>(state.range(1));
  const int kernel = static_cast<int>(state.range(2));
  omp_set_num_threads(threads);
  detail::generic_kernels_only() = kernel == 2;
  const std::vector<SweptTool> sw = raster(0.5);
  const Box stock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(100, 100, 20)};
  std::size_t tests = 0, mem = 0, dexels = 0, intervals = 0;
  CutStats stats;
  double max_err = 0, sum2 = 0, setup_ms = 0;
  int nodes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const auto t0 = std::chrono::steady_clock::now();
    DexelGrid z = make_zmap(stock, h);
    fill_box(z, stock);
    setup_ms += ms_since(t0);
    state.ResumeTiming();
    stats = kernel == 1 ? cut_reference(z, sw) : cut(z, sw);
    tests = stats.ray_tests;
    state.PauseTiming();
    max_err = 0, sum2 = 0, nodes = 0;
    for (int xi = 2; xi <= 98; ++xi) {
      const double e = envelope(xi);
      for (int yi = 2; yi <= 98; ++yi) {
        const double d = z.top(static_cast<int>(std::lround(xi / h)), static_cast<int>(std::lround(yi / h))) - e;
        max_err = std::max(max_err, std::abs(d));
        sum2 += d * d;
        ++nodes;
      }
    }
    mem = z.memory_bytes();
    dexels = static_cast<std::size_t>(z.nu()) * static_cast<std::size_t>(z.nv());
    intervals = z.interval_count();
    if (const char* prefix = std::getenv("VMSIM_REMOVAL_HEIGHTS")) {
      const std::string path = std::string(prefix) + "_" + std::to_string(n) + "_t" + std::to_string(threads) +
                               (kernel ? "_k" + std::to_string(kernel) : std::string()) + ".xyz";
      if (std::FILE* f = std::fopen(path.c_str(), "w")) {
        for (int xi = 1; xi <= 99; ++xi)
          for (int yi = 1; yi <= 99; ++yi)
            std::fprintf(f, "%d %d %.7f\n", xi, yi,
                         z.top(static_cast<int>(std::lround(xi / h)), static_cast<int>(std::lround(yi / h))));
        std::fclose(f);
      }
    }
    state.ResumeTiming();
  }
  omp_set_num_threads(omp_get_num_procs());
  detail::generic_kernels_only() = false;
  const double it = static_cast<double>(state.iterations());
  state.counters["ray_tests/s"] = benchmark::Counter(it * static_cast<double>(tests), benchmark::Counter::kIsRate);
  state.counters["ray_tests/s/thread"] =
      benchmark::Counter(it * static_cast<double>(tests) / threads, benchmark::Counter::kIsRate);
  state.counters["ray_tests"] = static_cast<double>(tests);
  if (kernel != 1) {
    const double t = static_cast<double>(tests);
    state.counters["tile_skip_%"] = 100.0 * static_cast<double>(stats.tile_skipped) / t;
    state.counters["bound_skip_%"] = 100.0 * static_cast<double>(stats.bound_skipped) / t;
    state.counters["exact_nil_%"] = 100.0 * static_cast<double>(stats.exact_nothing) / t;
    state.counters["cut_%"] = 100.0 * static_cast<double>(stats.cuts) / t;
    state.counters["order_free_blocks"] = static_cast<double>(stats.order_free_blocks);
    state.counters["replayed_rays"] = static_cast<double>(stats.replayed);
    state.counters["chunk_skipped"] = static_cast<double>(stats.chunk_skipped);
  }
  state.counters["max_err_um"] = max_err * 1e3;
  state.counters["rms_err_um"] = std::sqrt(sum2 / nodes) * 1e3;
  state.counters["sweeps"] = static_cast<double>(sw.size());
  state.counters["setup_ms"] = setup_ms / it;
  state.counters["dexels"] = static_cast<double>(dexels);
  state.counters["intervals"] = static_cast<double>(intervals);
  state.counters["zmap_MB"] = static_cast<double>(mem) / 1e6;
  state.counters["B/dexel"] = static_cast<double>(mem) / static_cast<double>(dexels);
}
BENCHMARK(BM_ZmapBallRaster)
    ->ArgNames({"n", "threads", "kernel"})
    ->Args({16, 1, 0})
    ->Args({16, 1, 1})
    ->Args({16, 1, 2})
    ->Args({32, 1, 0})
    ->Args({32, 1, 1})
    ->Args({32, 1, 2})
    ->Args({16, 2, 0})
    ->Args({32, 2, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A real CAM program's sweeps: CAMotics' flower_mold.nc (bench/flower_mold/job.toml, read from ../shared), read,
// interpolated at Te 1 ms on the Mikron and put through the forward transform: the setpoints' tool track (the drives'
// actual positions, vmsim run's default, add their following error and tip velocities, so 3.7 M track points and
// ~349 k sweeps where this track has fewer). Built once per process; not timed.
struct Flower {
  Tool tool;
  PoseTrack track;
  std::vector<SweptTool> sweeps;
  Box stock;
  std::string error;
};

const Flower& flower() {
  static const Flower f = [] {
    Flower r;
    const std::filesystem::path job_file = std::filesystem::path(VMSIM_SOURCE_DIR) / "bench/flower_mold/job.toml";
    try {
      const vmsim::core::Job job = vmsim::core::load_job(job_file);
      vmsim::program::ProgramOptions po;
      po.tool_table = job.tool_table_file;
      po.no_motion_mcodes = job.no_motion_mcodes;
      if (job.start_mm) po.start_mm = std::array<double, 3>{job.start_mm->x(), job.start_mm->y(), job.start_mm->z()};
      const vmsim::core::ToolPath program = vmsim::program::read_program(job.program_file, po);
      vmsim::motion::InterpOptions io;
      io.period_s = job.interp.period_s;
      io.tolerance_mm = job.interp.tolerance_mm;
      const vmsim::motion::InterpResult ir =
          vmsim::motion::interpolate(vmsim::motion::toolpath_in_axis_space(program, job.machine), job.machine, io);
      const auto kin = vmsim::motion::make_kinematics(job.machine);
      const vmsim::core::Setpoints& sp = ir.setpoints;
      r.track.period_s = sp.period_s;
      r.track.tip_mm.resize(sp.samples(), 3);
      for (Eigen::Index k = 0; k < sp.samples(); ++k) {
        const int mi = sp.move_index[k];
        const double tlo = mi >= 0 ? program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
        r.track.tip_mm.row(k) = kin->forward(sp.position.row(k).transpose(), tlo).tip_mm.transpose();
      }
      r.tool = make_tool(job.tool);
      r.sweeps = sweeps_from_track(r.tool, r.track).sweeps;
      r.stock = Box{job.stock.min_mm, job.stock.max_mm};
    } catch (const std::exception& e) {
      r.error = std::string(e.what()) + " (the program is read from ../shared/data/real/cam)";
    }
    return r;
  }();
  return f;
}

// VMSIM_FLOWER_TRACK=file: the actual track below read from that file when it exists, else built and written there
// (raw doubles: period, rows, tips, tip velocities; a scratch file for repeated runs of one build's benches, which
// spares the ~20 s of drive simulation per process; delete it when the motion chain changes).
bool load_track_cache(PoseTrack& t) {
  const char* path = std::getenv("VMSIM_FLOWER_TRACK");
  if (!path) return false;
  std::FILE* f = std::fopen(path, "rb");
  if (!f) return false;
  double head[2];
  bool ok = std::fread(head, sizeof head, 1, f) == 1 && head[1] > 0;
  if (ok) {
    const auto rows = static_cast<Eigen::Index>(head[1]);
    t.period_s = head[0];
    t.tip_mm.resize(rows, 3);
    t.tip_velocity_mm_per_s.resize(rows, 3);
    const std::size_t n = static_cast<std::size_t>(rows) * 3;
    ok = std::fread(t.tip_mm.data(), sizeof(double), n, f) == n &&
         std::fread(t.tip_velocity_mm_per_s.data(), sizeof(double), n, f) == n;
  }
  std::fclose(f);
  return ok;
}
void save_track_cache(const PoseTrack& t) {
  const char* path = std::getenv("VMSIM_FLOWER_TRACK");
  if (!path || t.tip_velocity_mm_per_s.rows() != t.tip_mm.rows() || t.axis_per_sample.size() > 0) return;
  std::FILE* f = std::fopen(path, "wb");
  if (!f) return;
  const double head[2] = {t.period_s, static_cast<double>(t.tip_mm.rows())};
  const std::size_t n = static_cast<std::size_t>(t.tip_mm.size());
  const bool ok = std::fwrite(head, sizeof head, 1, f) == 1 &&
                  std::fwrite(t.tip_mm.data(), sizeof(double), n, f) == n &&
                  std::fwrite(t.tip_velocity_mm_per_s.data(), sizeof(double), n, f) == n;
  if (std::fclose(f) != 0 || !ok) std::remove(path);
}

// The track vmsim run cuts on flower_mold (its default, motion = "actual"): the drives' actual positions and tip
// velocities (sim::motion_track, the streamed chain), ~3.7 M poses, and the job's sweeps (sim::sweeps_of: the
// default 0.1 um tolerance, the stock box), ~22x the programmed moves. Built once per process; not timed.
const Flower& flower_actual() {
  static const Flower f = [] {
    Flower r;
    const std::filesystem::path job_file = std::filesystem::path(VMSIM_SOURCE_DIR) / "bench/flower_mold/job.toml";
    try {
      const vmsim::core::Job job = vmsim::core::load_job(job_file);
      if (!load_track_cache(r.track)) {
        r.track = vmsim::sim::motion_track(vmsim::sim::Chain(job), vmsim::core::RemovalSpec::Motion::Actual,
                                           vmsim::core::no_progress());
        save_track_cache(r.track);
      }
      r.tool = make_tool(job.tool);
      r.sweeps = vmsim::sim::sweeps_of(job, r.track).sweeps;
      r.stock = Box{job.stock.min_mm, job.stock.max_mm};
    } catch (const std::exception& e) {
      r.error = std::string(e.what()) + " (the program is read from ../shared/data/real/cam)";
    }
    return r;
  }();
  return f;
}

// The track of flower_mold's setpoints to sweeps (default 0.1 um tolerance). Argument: 0 sweeps_from_track, 1 its
// reference (removal/cut_reference.hpp).
void BM_FlowerTrack(benchmark::State& state) {
  const Flower& f = flower();
  if (!f.error.empty()) return state.SkipWithError(f.error.c_str());
  std::size_t sweeps = 0;
  for (auto _ : state) {
    const TrackSweeps t =
        state.range(0) == 1 ? sweeps_from_track_reference(f.tool, f.track) : sweeps_from_track(f.tool, f.track);
    sweeps = t.sweeps.size();
  }
  state.counters["poses"] = static_cast<double>(f.track.tip_mm.rows());
  state.counters["sweeps"] = static_cast<double>(sweeps);
  state.counters["ns/pose"] =
      benchmark::Counter(static_cast<double>(f.track.tip_mm.rows()) * 1e-9,
                         benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_FlowerTrack)->ArgNames({"kernel"})->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Those sweeps cut from the box stock on a z-map at 1/n mm, one thread. Kernel as BM_ZmapBallRaster's.
// The cut's statistics as the bench's counters (the reference kernel counts only its ray tests).
void put_cut_counters(benchmark::State& state, std::size_t sweeps, const CutStats& stats, bool fast, bool replayed) {
  state.counters["sweeps"] = static_cast<double>(sweeps);
  state.counters["ray_tests"] = static_cast<double>(stats.ray_tests);
  if (!fast) return;
  const double t = static_cast<double>(stats.ray_tests);
  state.counters["tile_skip_%"] = 100.0 * static_cast<double>(stats.tile_skipped) / t;
  state.counters["bound_skip_%"] = 100.0 * static_cast<double>(stats.bound_skipped) / t;
  state.counters["exact_nil_%"] = 100.0 * static_cast<double>(stats.exact_nothing) / t;
  state.counters["cut_%"] = 100.0 * static_cast<double>(stats.cuts) / t;
  state.counters["order_free_blocks"] = static_cast<double>(stats.order_free_blocks);
  state.counters["chunk_skipped"] = static_cast<double>(stats.chunk_skipped);
  if (replayed) state.counters["replayed"] = static_cast<double>(stats.replayed);
}

void BM_FlowerZmap(benchmark::State& state) {
  const Flower& f = flower();
  if (!f.error.empty()) return state.SkipWithError(f.error.c_str());
  const double h = 1.0 / static_cast<double>(state.range(0));
  const int kernel = static_cast<int>(state.range(1));
  omp_set_num_threads(1);
  detail::generic_kernels_only() = kernel == 2;
  CutStats stats;
  for (auto _ : state) {
    state.PauseTiming();
    DexelGrid z = make_zmap(f.stock, h);
    fill_box(z, f.stock);
    state.ResumeTiming();
    stats = kernel == 1 ? cut_reference(z, f.sweeps) : cut(z, f.sweeps);
  }
  omp_set_num_threads(omp_get_num_procs());
  detail::generic_kernels_only() = false;
  put_cut_counters(state, f.sweeps.size(), stats, kernel != 1, false);
}
BENCHMARK(BM_FlowerZmap)
    ->ArgNames({"n", "kernel"})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({40, 0})
    ->Args({40, 1})
    ->Unit(benchmark::kMillisecond);

// vmsim run's own removal on flower_mold at 0.1 mm: the actual motion's track to sweeps (track 1: timed with the
// same options as sim::sweeps_of, the stock box, which a 3-axis track does not use) and those sweeps cut from the box
// stock on the z-map (kernel as BM_ZmapBallRaster's), with `threads` OpenMP threads. What report.json's removal_cpu
// holds, less the field's set-up. batch: the sweeps in one cut() call (0), in one call that reports its progress (-1:
// bands of rows, as sim::cut_field calls it since issue 21's session 8), or in calls of that many sweeps (4096: how
// sim::cut_field reported progress before).
void BM_FlowerActualTrack(benchmark::State& state) {
  const Flower& f = flower_actual();
  if (!f.error.empty()) return state.SkipWithError(f.error.c_str());
  TrackOptions opt;
  opt.material_box = Eigen::AlignedBox3d(f.stock.lo, f.stock.hi);
  std::size_t sweeps = 0;
  for (auto _ : state) sweeps = sweeps_from_track(f.tool, f.track, opt).sweeps.size();
  state.counters["poses"] = static_cast<double>(f.track.tip_mm.rows());
  state.counters["sweeps"] = static_cast<double>(sweeps);
  state.counters["ns/pose"] =
      benchmark::Counter(static_cast<double>(f.track.tip_mm.rows()) * 1e-9,
                         benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_FlowerActualTrack)->Unit(benchmark::kMillisecond);

// A checksum of every ray's top and bottom (FNV-1a over their bits, 48 bits: a counter holds it exactly), so that
// two builds' benches show whether their cuts agree bit for bit.
double heights_checksum(const DexelGrid& z) {
  std::uint64_t h = 1469598103934665603ull;
  for (int j = 0; j < z.nv(); ++j)
    for (int i = 0; i < z.nu(); ++i) {
      const double v[2] = {z.top(i, j), z.bottom(i, j)};
      unsigned char b[sizeof v];
      std::memcpy(b, v, sizeof v);
      for (unsigned char c : b) h = (h ^ c) * 1099511628211ull;
    }
  return static_cast<double>(h & ((std::uint64_t{1} << 48) - 1));
}

void BM_FlowerActualZmap(benchmark::State& state) {
  const Flower& f = flower_actual();
  if (!f.error.empty()) return state.SkipWithError(f.error.c_str());
  const double h = 1.0 / static_cast<double>(state.range(0));
  const int kernel = static_cast<int>(state.range(1));
  omp_set_num_threads(static_cast<int>(state.range(2)));
  const long batch = static_cast<long>(state.range(3));
  detail::generic_kernels_only() = kernel == 2;
  CutStats stats;
  double checksum = 0;
  for (auto _ : state) {
    state.PauseTiming();
    DexelGrid z = make_zmap(f.stock, h);
    fill_box(z, f.stock);
    state.ResumeTiming();
    struct Sum {  // the checksum after each timed cut, outside the timed region
      benchmark::State& st;
      const DexelGrid& g;
      double& out;
      ~Sum() {
        st.PauseTiming();
        out = heights_checksum(g);
        st.ResumeTiming();
      }
    } sum{state, z, checksum};
    if (batch <= 0) {
      stats = kernel == 1 ? cut_reference(z, f.sweeps)
                          : (batch == 0 ? cut(z, f.sweeps) : cut(z, f.sweeps, &vmsim::core::no_progress(), 0));
      continue;
    }
    stats = CutStats{};
    for (std::size_t b = 0; b < f.sweeps.size(); b += static_cast<std::size_t>(batch)) {
      const std::size_t e = std::min(f.sweeps.size(), b + static_cast<std::size_t>(batch));
      const std::vector<SweptTool> part(f.sweeps.begin() + static_cast<std::ptrdiff_t>(b),
                                        f.sweeps.begin() + static_cast<std::ptrdiff_t>(e));
      const CutStats s = kernel == 1 ? cut_reference(z, part) : cut(z, part);
      stats.ray_tests += s.ray_tests, stats.cuts += s.cuts, stats.tile_skipped += s.tile_skipped;
      stats.bound_skipped += s.bound_skipped, stats.exact_nothing += s.exact_nothing;
      stats.order_free_blocks += s.order_free_blocks, stats.chunk_skipped += s.chunk_skipped,
          stats.replayed += s.replayed;
    }
  }
  omp_set_num_threads(omp_get_num_procs());
  detail::generic_kernels_only() = false;
  put_cut_counters(state, f.sweeps.size(), stats, kernel != 1, true);
  state.counters["checksum"] = checksum;
}
BENCHMARK(BM_FlowerActualZmap)
    ->ArgNames({"n", "kernel", "threads", "batch"})
    ->Args({10, 0, 1, 0})
    ->Args({10, 0, 1, -1})
    ->Args({10, 0, 1, 4096})
    ->Args({10, 2, 1, 0})
    ->Args({10, 0, 2, -1})
    ->Args({10, 0, 2, 4096})
    ->Unit(benchmark::kMillisecond);

}  // namespace

namespace {

double cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// How the removal's cost grows (bench/README.md's cost-growth table): flower_mold's setpoint track repeated r times,
// each copy 0.2 mm deeper (r x the moves, each copy cutting), to sweeps and through the z-map at 1/n mm, one thread.
// Counters: the CPU seconds of sweeps_from_track and of cut(), and the memory the removal holds: the z-map, the
// sweeps (96 B each) and the track's tips (24 B per pose).
void BM_FlowerGrowth(benchmark::State& state) {
  const Flower& f = flower();
  if (!f.error.empty()) return state.SkipWithError(f.error.c_str());
  const double h = 1.0 / static_cast<double>(state.range(0));
  const int copies = static_cast<int>(state.range(1));
  PoseTrack tr;
  tr.period_s = f.track.period_s;
  const Eigen::Index n = f.track.tip_mm.rows();
  tr.tip_mm.resize(n * copies, 3);
  for (int c = 0; c < copies; ++c) {
    tr.tip_mm.middleRows(c * n, n) = f.track.tip_mm;
    tr.tip_mm.middleRows(c * n, n).col(2).array() -= 0.2 * c;
  }
  omp_set_num_threads(1);
  double track_s = 0, cut_s = 0;
  std::size_t sweeps = 0, zmap_bytes = 0;
  for (auto _ : state) {
    double t0 = cpu_seconds();
    const TrackSweeps ts = sweeps_from_track(f.tool, tr);
    track_s = cpu_seconds() - t0;
    state.PauseTiming();
    DexelGrid z = make_zmap(f.stock, h);
    fill_box(z, f.stock);
    state.ResumeTiming();
    t0 = cpu_seconds();
    cut(z, ts.sweeps);
    cut_s = cpu_seconds() - t0;
    sweeps = ts.sweeps.size();
    zmap_bytes = z.memory_bytes();
  }
  omp_set_num_threads(omp_get_num_procs());
  state.counters["poses"] = static_cast<double>(tr.tip_mm.rows());
  state.counters["sweeps"] = static_cast<double>(sweeps);
  state.counters["track_cpu_s"] = track_s;
  state.counters["cut_cpu_s"] = cut_s;
  state.counters["zmap_MB"] = static_cast<double>(zmap_bytes) / 1e6;
  state.counters["sweeps_MB"] = static_cast<double>(sweeps * sizeof(SweptTool)) / 1e6;
  state.counters["track_MB"] = static_cast<double>(tr.tip_mm.size() * sizeof(double)) / 1e6;
}
BENCHMARK(BM_FlowerGrowth)
    ->ArgNames({"n", "copies"})
    ->Args({5, 1})
    ->Args({10, 1})
    ->Args({20, 1})
    ->Args({40, 1})
    ->Args({10, 4})
    ->Args({10, 16})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

}  // namespace
