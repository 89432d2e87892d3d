#pragma once
// report.json: the machine-readable summary of every run (inputs with their hashes, figures, files, timings).
#include "sim/report.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>

namespace vmsim::app {

using sim::report_header;

// Written atomically (temporary file, then rename), pretty-printed; a report.json gets its report.html beside it.
void write_report(const std::filesystem::path& file, const nlohmann::json& report);

}  // namespace vmsim::app
