// vmsim render DIR: the pictures of a result directory written by vmsim run or vmsim motion, into DIR/images (and
// DIR/report.html again, to show them).
#include "app/commands.hpp"
#include "app/result_images.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "render/report_html.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>

namespace vmsim::app {

int run_render(const RenderArgs& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const ImageOptions opt = image_options(args.images);
  // DIR's lock while reading it and writing its pictures: a run replacing DIR meanwhile would mix two results.
  const core::OutputLock lock(args.dir, "vmsim render");
  const ResultData data = load_results(args.dir);
  const std::filesystem::path out = args.out_dir.value_or(args.dir / "images");
  const std::vector<std::string> files = write_result_images(data, out, opt);
  for (const std::string& f : files) std::printf("%s\n", (out / f).string().c_str());
  // The directory's page shows the pictures now there (not when they go elsewhere, or with other colour limits
  // than the report's deviation gives: the page states those).
  if (!args.out_dir && !args.images.limit_um && std::filesystem::exists(args.dir / "report.json")) {
    std::ifstream in(args.dir / "report.json");
    render::write_report_html(args.dir, nlohmann::json::parse(in));
  }
  std::fprintf(stderr, "vmsim render: %zu images (%dx%d) in %.1f s\n", files.size(), opt.width, opt.height,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}

}  // namespace vmsim::app
