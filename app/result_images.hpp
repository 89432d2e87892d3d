#pragma once
// The pictures of a result directory: `vmsim run` draws them from memory into DIR/images, `vmsim render DIR` from
// the files run and motion wrote (surface.csv, deviation.csv, report.json, signals.csv).
#include "app/commands.hpp"
#include "sim/signals.hpp"
#include "core/height_grid.hpp"
#include "metrology/marks.hpp"
#include "render/scene.hpp"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

struct ResultData {
  std::string job;                            // for the captions
  std::string reference;                      // what the deviation is measured from (report.json "reference")
  std::optional<core::HeightGrid> surface;    // predicted surface
  std::optional<core::HeightGrid> deviation;  // surface - reference, same grid
  // How the deviation is measured (report.json surface.deviation_along): "normal" (along the reference's normal,
  // what vmsim run writes) or "vertical" (results written before it did).
  std::string deviation_along = "normal";
  std::vector<metrology::Mark> marks;         // deepest first
  std::optional<sim::BinnedSignals> signals;
  // A job with several tools (vmsim run only): per surface node the index of the tool that last cut it (-1 uncut),
  // and each tool's legend entry (tools.png).
  std::optional<Eigen::ArrayXXi> tool_index;
  std::vector<std::string> tool_names;
};

// A tool's legend entry in tools.png from its report.json tools.list entry: "T1 flat D6.35".
std::string tool_legend(const nlohmann::json& tool);

struct ImageOptions {
  int width = 1600, height = 1200;
  double vertical_exaggeration = 1.0;        // every part picture
  std::optional<render::Region> region;      // the zoom pictures' region; default: around the deepest mark
  double limit_mm = 0.0;                     // colour limits; 0: max |deviation| rounded up
  int isolines = 3;                          // per side of zero in the deviation maps
  double mark_magnification = 0.0;           // part_mark.png; 0: chosen from the mark's depth
  std::optional<double> path_direction_deg;  // along-the-path views; default: from the signals (+X or +Y)
};

// "1600x1200" -> (1600, 1200); throws core::Error unless WIDTHxHEIGHT, each 16..16384.
std::pair<int, int> parse_image_size(const std::string& text);
// The command line's picture options, checked.
ImageOptions image_options(const ImageArgs& args);

// Reads what a result directory holds: surface.csv, deviation.csv, report.json (job, reference), signals.csv; the
// marks are found again in the deviation (as `vmsim run` finds them, > 1 um). Throws core::Error when the
// directory holds none of surface.csv, deviation.csv and signals.csv.
ResultData load_results(const std::filesystem::path& dir);

// Draws every picture the data allows into `image_dir` (created) and returns the file names written, in order.
// Throws core::Error (e.g. no EGL context: see render::Window) with what to do.
std::vector<std::string> write_result_images(const ResultData& data, const std::filesystem::path& image_dir,
                                             const ImageOptions& options);

}  // namespace vmsim::app
