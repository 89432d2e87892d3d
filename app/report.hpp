#pragma once
// report.json: the machine-readable summary of every run (inputs with their hashes, figures, files, timings).
#include "core/job.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace vmsim::app {

// {"vmsim": version, "command": ..., "job": name, "inputs": {job, machine, program, tool_table: {path, sha256}}}
nlohmann::json report_header(const std::string& command, const core::Job& job);

// Written atomically (temporary file, then rename), pretty-printed; a report.json gets its report.html beside it.
void write_report(const std::filesystem::path& file, const nlohmann::json& report);

}  // namespace vmsim::app
