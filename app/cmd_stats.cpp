// vmsim stats SURFACE: what a surface file holds and its ISO 25178-2 areal parameters (a profile: its ISO 21920-2
// profile parameters), as JSON on stdout. With --level none the parameters are those of the raw heights about their
// mean, for checking against Gwyddion or MountainsMap.
#include "app/cmd_surface.hpp"
#include "app/commands.hpp"
#include "core/error.hpp"
#include "metrology/processing.hpp"
#include "metrology/surface_io.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>

namespace vmsim::app {

int run_stats(const StatsArgs& args) {
  const metrology::SurfaceProcessing how = parse_processing(args.options);
  metrology::SurfaceFile f = metrology::read_surface_file(args.surface);
  if (!f.note.empty())
    std::fprintf(stderr, "vmsim stats: warning: %s: %s\n", args.surface.string().c_str(), f.note.c_str());
  nlohmann::ordered_json out;  // in reading order: the file, its grid, what was done, the parameters
  out["file"] = input_json(args.surface, f.format);
  if (f.profile) {
    // A profile (1-D): its ISO 21920-2 parameters (metrology/profile.hpp says how they are evaluated).
    if (args.options.outlier_sigma > 0)
      throw core::Error("--outliers: spike masking works on surfaces; this file holds a profile");
    out["profile"] = line_scan_json(*f.profile);
    if (!f.note.empty()) out["note"] = f.note;
    const metrology::ProfileEvaluation pe = metrology::profile_evaluation(how);
    const auto e = metrology::evaluate_profile(profile_in_range(*f.profile, args.options.profile_range), pe);
    out["profile_parameters"] = profile_json(e, pe);
    std::printf("%s\n", out.dump(2).c_str());
    return 0;
  }
  if (!args.options.profile_range.empty()) throw core::Error("--range: applies to profiles; this file holds a surface");
  out["grid"] = grid_json(f.grid);
  if (!f.note.empty()) out["note"] = f.note;
  const metrology::SurfaceAnalysis a = metrology::analyse_surface(std::move(f.grid), how, args.options.outlier_sigma);
  if (a.outliers)
    out["outliers"] = {{"masked", a.outliers->masked},
                       {"k_sigma", args.options.outlier_sigma},
                       {"sigma_mm", a.outliers->sigma_mm},
                       {"threshold_mm", a.outliers->threshold_mm}};
  out["processing"] = processing_json(how, a.form);
  out["areal"] = areal_json(a.areal);
  out["areal"]["reference"] =
      how.level > 0 ? "the least-squares form removed (heights from it)" : "the mean of the valid heights";
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

}  // namespace vmsim::app
