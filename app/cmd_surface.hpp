#pragma once
// Helpers shared by the surface commands (vmsim compare, stats, measure): lengths with units on the command line,
// the form removal and filter options, and their JSON for report.json and stdout.
#include "core/height_grid.hpp"
#include "core/output_dir.hpp"
#include "metrology/areal.hpp"
#include "metrology/form.hpp"
#include "metrology/processing.hpp"
#include "metrology/profile.hpp"
#include "metrology/surface_io.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

// "5um", "0.005", "0.005 mm", "2e-3mm": a length in mm (no unit: mm). Throws core::Error naming `option`.
double parse_length_mm(const std::string& text, const std::string& option);

// --level none | plane | poly:N -> 0, 1, N.
int parse_level(const std::string& text);

// --filter S:<cut-off> (S-filter: keeps the mean surface, removes shorter wavelengths) or L:<cut-off> (L-filter:
// removes the mean surface, keeps the roughness), Gaussian (ISO 16610-61); cut-offs are lengths with units.
std::vector<metrology::SurfaceFilter> parse_filters(const std::vector<std::string>& texts);

struct SurfaceOptions;
// --level and --filter as one processing (metrology/processing.hpp).
metrology::SurfaceProcessing parse_processing(const SurfaceOptions& options);
// What the processing did, for report.json: the form removed (with its fit when `form` is given) and the filters.
nlohmann::json processing_json(const metrology::SurfaceProcessing& how, const std::optional<metrology::FormFit>& form);

nlohmann::json areal_json(const metrology::ArealParameters& p);

// Profiles: --range "X0,X1" applied (the samples from the one nearest to X0 to the one nearest to X1; an empty text
// keeps the whole trace), and the JSON of the trace and of its ISO 21920-2 parameters.
metrology::LineScan profile_in_range(const metrology::LineScan& p, const std::string& range);
nlohmann::json line_scan_json(const metrology::LineScan& p);
nlohmann::json profile_json(const metrology::EvaluatedProfile& e, const metrology::ProfileEvaluation& how);

struct CompareArgs;
// vmsim compare with a measured profile (cmd_compare_profile.cpp): the profile against --profile-line across PRED.
// OUT: the output directory run_compare locked (written in its staging directory, committed here).
int run_compare_profile(const CompareArgs& args, const metrology::SurfaceFile& measured, core::OutputDir& out);
nlohmann::json grid_json(const core::HeightGrid& g);  // size, spacing, origin, valid and invalid points
// {path, sha256, format}
nlohmann::json input_json(const std::filesystem::path& file, const std::string& format);

}  // namespace vmsim::app
