// Off-screen rendering (render/): a part of about one million triangles to a 1600 x 1200 PNG on the headless
// Mesa EGL window (llvmpipe, no GPU, no X server).
//
// The part: a 708 x 708 height grid over 70.7 x 70.7 mm (0.1 mm spacing), a wavy surface with a groove, as a
// TriangleMesh of 999 698 triangles (2 per cell, as removal::heightfield_mesh triangulates a grid) with a per-vertex
// "deviation_mm", and as the HeightGrid itself (the same triangles plus side walls).
// Each iteration: VTK polydata from the vmsim value type (and normals), render, read the pixels back, encode and
// write the PNG (to $TMPDIR). One window for all iterations, as vmsim run and render draw all their pictures in one;
// BM_FirstPicture makes a new window (EGL context, shader compilation) every time.
// Counters: triangles per second; the time of the PNG step alone is BM_EncodePng. cpu_ms_per_picture is the CPU of
// the whole process (llvmpipe's render threads included; the benchmark's own CPU column counts the calling thread).
// Antialiasing (last argument of BM_GridToPng and BM_ChartToPng): 0 none, 1 FXAA (on the CPU), 2 4x MSAA, 3 FXAA as
// VTK's shader. Figures: bench/README.md.
#include "render/chart.hpp"
#include "render/fxaa.hpp"
#include "render/image.hpp"
#include "render/scene.hpp"
#include "render/window.hpp"

#include "core/timing.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

namespace {

using namespace vmsim;

constexpr int kN = 708;  // nodes per side: 2 * 707^2 = 999 698 triangles

double height(double x, double y) {
  return 0.5 * std::sin(x / 7) * std::cos(y / 9) + 0.02 * std::sin(x * 3) -
         0.05 * std::exp(-std::pow((y - 35) / 1.5, 2));
}

const core::HeightGrid& grid() {
  static const core::HeightGrid g = [] {
    core::HeightGrid h;
    h.dx_mm = h.dy_mm = 0.1;
    h.z_mm.resize(kN, kN);
    for (Eigen::Index j = 0; j < kN; ++j)
      for (Eigen::Index i = 0; i < kN; ++i) h.z_mm(j, i) = height(h.x(i), h.y(j));
    return h;
  }();
  return g;
}

const core::HeightGrid& deviation() {
  static const core::HeightGrid d = [] {
    core::HeightGrid h = grid();
    for (Eigen::Index j = 0; j < kN; ++j)
      for (Eigen::Index i = 0; i < kN; ++i)
        h.z_mm(j, i) = 0.015 * std::exp(-std::pow((h.x(i) - 40) / 4, 2)) * std::sin(h.y(j) / 5);
    return h;
  }();
  return d;
}

const core::TriangleMesh& mesh() {
  static const core::TriangleMesh m = [] {
    core::TriangleMesh t;
    const core::HeightGrid& g = grid();
    t.vertices_mm.resize(kN * kN, 3);
    Eigen::VectorXd dev(kN * kN);
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        t.vertices_mm.row(j * kN + i) << g.x(i), g.y(j), g.z_mm(j, i);
        dev[j * kN + i] = deviation().z_mm(j, i);
      }
    t.triangles.resize(2 * (kN - 1) * (kN - 1), 3);
    int k = 0;
    for (int j = 0; j + 1 < kN; ++j)
      for (int i = 0; i + 1 < kN; ++i) {
        const int a = j * kN + i;
        t.triangles.row(k++) << a, a + 1, a + kN + 1;
        t.triangles.row(k++) << a, a + kN + 1, a + kN;
      }
    t.point_data.emplace_back("deviation_mm", dev);
    return t;
  }();
  return m;
}

render::Window& window() {
  static std::unique_ptr<render::Window> w = [] {
    ::unsetenv("DISPLAY");
    return std::make_unique<render::Window>();
  }();
  return *w;
}

const std::filesystem::path png = std::filesystem::temp_directory_path() / "vmsim_render_bench.png";

const char* aa_name(std::int64_t a) {
  return a == 0 ? "no AA" : a == 1 ? "FXAA (CPU)" : a == 2 ? "4x MSAA" : "FXAA (VTK's shader)";
}

// CPU of every thread of the process per iteration, from the first to the last.
struct ProcessCpu {
  double t0 = core::process_cpu_s();
  void report(benchmark::State& state) const {
    state.counters["cpu_ms_per_picture"] =
        benchmark::Counter((core::process_cpu_s() - t0) * 1e3 / static_cast<double>(state.iterations()));
  }
};

render::PartPicture picture(bool coloured, render::ViewDirection dir) {
  render::PartPicture p;
  p.width = 1600, p.height = 1200;
  p.caption = {"render bench", "one million triangles"};
  p.view.direction = dir;
  if (coloured) {
    p.deviation = render::DeviationColours{};
    p.deviation->isolines = 3;
    p.deviation->lit = dir != render::ViewDirection::Top;
  }
  return p;
}

void BM_MeshToPng(benchmark::State& state) {
  const core::TriangleMesh& m = mesh();
  const auto pic = picture(state.range(0) != 0, render::ViewDirection::Isometric);
  render::Window& w = window();
  for (auto _ : state) {
    const render::PartImage img = render::render_part(w, m, pic);
    render::write_png(png, img.image);
  }
  state.counters["triangles"] = static_cast<double>(m.triangles.rows());
  state.counters["triangles_per_s"] =
      benchmark::Counter(static_cast<double>(m.triangles.rows()), benchmark::Counter::kIsIterationInvariantRate);
  state.SetLabel(state.range(0) ? "deviation colours, lit, iso-lines" : "plain metal");
}
BENCHMARK(BM_MeshToPng)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_GridToPng(benchmark::State& state) {
  const auto dir = static_cast<render::ViewDirection>(state.range(0));
  auto pic = picture(state.range(1) != 0, dir);
  pic.antialiasing = static_cast<render::Antialiasing>(state.range(2));
  render::Window& w = window();
  render::render_part(w, grid(), &deviation(), pic);  // shaders compiled outside the timing
  const ProcessCpu cpu;
  for (auto _ : state) {
    const render::PartImage img = render::render_part(w, grid(), &deviation(), pic);
    render::write_png(png, img.image);
  }
  cpu.report(state);
  state.counters["triangles_per_s"] =
      benchmark::Counter(2.0 * (kN - 1) * (kN - 1), benchmark::Counter::kIsIterationInvariantRate);
  state.SetLabel(std::string(dir == render::ViewDirection::Top ? "top map" : "isometric") +
                 (state.range(1) ? ", deviation colours" : ", plain metal") + ", " + aa_name(state.range(2)));
}
BENCHMARK(BM_GridToPng)
    ->Args({0, 0, 0})
    ->Args({0, 0, 1})
    ->Args({0, 0, 2})
    ->Args({0, 0, 3})
    ->Args({1, 1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The flat top map (deviation colours, 3 iso-lines per side, no lighting) of the million-triangle grid: drawn as
// one image coloured per pixel on the CPU (1) or as its triangles (0, every map before).
void BM_MapToPng(benchmark::State& state) {
  auto pic = picture(true, render::ViewDirection::Top);
  pic.map_as_image = state.range(0) != 0;
  pic.deviation->isolines = static_cast<int>(state.range(1));
  render::Window& w = window();
  render::render_part(w, grid(), &deviation(), pic);  // shaders compiled outside the timing
  const ProcessCpu cpu;
  for (auto _ : state) {
    const render::PartImage img = render::render_part(w, grid(), &deviation(), pic);
    render::write_png(png, img.image);
  }
  cpu.report(state);
  state.SetLabel(std::string("top map, ") + (pic.map_as_image ? "image" : "triangles") + ", " +
                 std::to_string(pic.deviation->isolines) + " iso-lines per side");
}
BENCHMARK(BM_MapToPng)->ArgsProduct({{0, 1}, {0, 3}})->Unit(benchmark::kMillisecond)->UseRealTime();

const char* filter_name(std::int64_t f) {
  static const char* names[] = {"none", "sub", "up", "paeth", "adaptive"};
  return names[f];
}

// PNG encoding alone (calling thread's CPU = all of it), by picture, row filter, zlib level and strategy.
// Pictures: 0 the isometric part (plain metal, FXAA), 1 the top map (deviation colours, iso-lines), 2 three charts.
// Three stacked charts of 20 000 points per series (setpoint, then actual a little off), a limit on each.
render::ChartPicture three_charts(int series_per_chart, double width_px) {
  render::ChartPicture p;
  p.width = 1600, p.height = 1200;
  for (int c = 0; c < 3; ++c) {
    render::Chart ch;
    ch.x_title = "t [s]";
    ch.y_title = "v [mm/s]";
    for (int s = 0; s < series_per_chart; ++s) {
      const Eigen::ArrayXd x = Eigen::ArrayXd::LinSpaced(20000, 0, 100);
      ch.series.push_back(render::make_series(s ? "actual" : "setpoint", x, (x * (c + 1 + 0.1 * s)).sin() * 100, s,
                                              width_px));
    }
    ch.levels.push_back({"limit", 120});
    p.charts.push_back(ch);
  }
  return p;
}

void BM_EncodePng(benchmark::State& state) {
  static const render::Image part =
      render::render_part(window(), grid(), nullptr, picture(false, render::ViewDirection::Isometric)).image;
  static const render::Image map =
      render::render_part(window(), grid(), &deviation(), picture(true, render::ViewDirection::Top)).image;
  static const render::Image chart = render::render_charts(window(), three_charts(1, 1.6)).image;
  const render::Image* images[] = {&part, &map, &chart};
  const render::Image& img = *images[state.range(0)];
  render::PngEncoding enc;
  enc.filter = static_cast<render::PngFilter>(state.range(1));
  enc.level = static_cast<int>(state.range(2));
  enc.rle = state.range(3) != 0;
  enc.deflater = state.range(4) != 0 ? render::PngDeflater::Libdeflate : render::PngDeflater::Zlib;
  std::size_t bytes = 0;
  for (auto _ : state) bytes = render::encode_png(img, enc).size();
  state.counters["bytes"] = static_cast<double>(bytes);
  static const char* kinds[] = {"part", "map", "chart"};
  state.SetLabel(std::string(kinds[state.range(0)]) + ", filter " + filter_name(state.range(1)) +
                 (state.range(4) ? ", libdeflate " : ", zlib ") + std::to_string(enc.level) + (enc.rle ? " RLE" : ""));
}
// Arguments: picture, filter, level, RLE, deflater (0 zlib through libpng, 1 libdeflate).
BENCHMARK(BM_EncodePng)
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2, 4}, {1, 3}, {0}, {0}})
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2}, {1}, {1}, {0}})
    ->ArgsProduct({{0, 1, 2}, {4}, {5}, {0}, {0}})
    ->ArgsProduct({{0, 1, 2}, {2}, {1, 2, 3, 4, 6}, {0}, {1}})
    ->Unit(benchmark::kMillisecond);

void BM_ChartToPng(benchmark::State& state) {
  render::ChartPicture p = three_charts(2, 2.0);
  p.antialiasing = static_cast<render::Antialiasing>(state.range(0));
  render::render_charts(window(), p);
  const ProcessCpu cpu;
  for (auto _ : state) render::write_png(png, render::render_charts(window(), p).image);
  cpu.report(state);
  state.SetLabel(std::string("3 stacked charts, 2 x 20 000 points each, limits, ") + aa_name(state.range(0)));
}
BENCHMARK(BM_ChartToPng)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FirstPicture(benchmark::State& state) {
  render::PartPicture p = picture(false, render::ViewDirection::Isometric);
  core::HeightGrid small = grid();
  small.z_mm = grid().z_mm.topLeftCorner(50, 50);
  for (auto _ : state) {
    render::Window w;  // EGL context, VTK window, shader compilation on the first picture
    benchmark::DoNotOptimize(render::render_part(w, small, nullptr, p).image.rgb.data());
  }
  state.SetLabel("new window + one small 1600x1200 picture");
}
BENCHMARK(BM_FirstPicture)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);

}  // namespace

// FXAA on the CPU (render/fxaa.hpp) over a whole 1600 x 1200 isometric part picture drawn without antialiasing: what
// Antialiasing::Fxaa adds to a 3-D view (VTK's shader, Antialiasing::FxaaVtk: compare BM_GridToPng/0/0/3 with /0/0/0).
void BM_FxaaCpu(benchmark::State& state) {
  render::PartPicture p = picture(false, render::ViewDirection::Isometric);
  p.antialiasing = render::Antialiasing::None;
  const render::Image plain = render::render_part(window(), grid(), nullptr, p).image;
  for (auto _ : state) {
    render::Image img = plain;
    render::fxaa(img, render::PixelRect{0, 0, img.width, img.height});
    benchmark::DoNotOptimize(img.rgb.data());
  }
  state.SetLabel("1600 x 1200 part picture (calling thread's CPU = all of it; includes a 5.8 MB copy)");
}
BENCHMARK(BM_FxaaCpu)->Unit(benchmark::kMillisecond);

// A picture's costs that do not grow with the triangles: a 50 x 50-node part (a few thousand triangles) framed to fill
// the viewport (lit fragments, background, captions, antialiasing, read-back), by antialiasing (0 none, 1 FXAA on
// the CPU, 3 VTK's FXAA shader).
void BM_SmallPart(benchmark::State& state) {
  render::PartPicture p = picture(false, render::ViewDirection::Isometric);
  p.antialiasing = static_cast<render::Antialiasing>(state.range(0));
  core::HeightGrid small = grid();
  small.z_mm = grid().z_mm.topLeftCorner(50, 50);
  render::render_part(window(), small, nullptr, p);
  const ProcessCpu cpu;
  for (auto _ : state) benchmark::DoNotOptimize(render::render_part(window(), small, nullptr, p).image.rgb.data());
  cpu.report(state);
}
BENCHMARK(BM_SmallPart)->Arg(0)->Arg(1)->Arg(3)->Unit(benchmark::kMillisecond)->UseRealTime();
