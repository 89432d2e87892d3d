#pragma once
// report.json: the machine-readable summary of every run (inputs with their hashes, figures, files, timings).
#include "sim/report.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>

namespace vmsim::app {

using sim::report_header;

// Written atomically (temporary file, then rename), pretty-printed; a report.json gets its report.html beside it.
void write_report(const std::filesystem::path& file, const nlohmann::json& report);

// Prints report.json's warnings on stderr, one line each, and the verdict when it is not "ok". Returns the
// command's exit code: sim::kExitInvalid for the verdict "invalid", else 0.
int print_verdict(const nlohmann::json& report);

}  // namespace vmsim::app
