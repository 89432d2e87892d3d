#pragma once
// report.json: the machine-readable summary of every run (inputs with their hashes, figures, files, timings).
#include "sim/report.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

using sim::report_header;

// Written atomically (temporary file, then rename), pretty-printed; a report.json gets its report.html beside it.
void write_report(const std::filesystem::path& file, const nlohmann::json& report);

// Prints report.json's warnings on stderr, one line each, and the verdict when it is not "ok". Returns the
// command's exit code: sim::kExitInvalid for the verdict "invalid", else 0.
int print_verdict(const nlohmann::json& report);
// A result directory's report.json, read back. Throws core::Error naming DIR when it is absent (the directory is not
// a complete result of vmsim) or not JSON.
nlohmann::json read_report(const std::filesystem::path& dir);
// The names its "files" lists (relative to DIR; "images/part.png" for a picture).
std::vector<std::string> listed_files(const nlohmann::json& report);
// A file read from a result directory of vmsim (one holding report.json or the marker of core/output_dir.hpp) must be
// listed in its report.json: a file an earlier run left, or one of a run that did not finish, would pass for this
// run's. Throws core::Error naming the file and what is missing; a file from anywhere else passes.
void require_listed_in_report(const std::filesystem::path& file);
// Refuses, before any work, an input path that report.json could not hold (not valid UTF-8 once made absolute),
// naming WHAT (e.g. "--measured") and the path.
void require_utf8_input(const std::filesystem::path& file, const char* what);
// Where a command writes without --out: NAME_COMMAND in the current directory (e.g. plane_cylinder_fast_run/), so
// a second command or job does not replace the first's result, and the current directory itself (which
// core::OutputDir cannot swap) is never the target. NAME is the job's name or the input file's stem; characters
// other than letters, digits, '.', '-' and '_' become '_'.
std::filesystem::path out_dir_or_default(const std::optional<std::filesystem::path>& out_dir, const std::string& name,
                                         const char* command);

}  // namespace vmsim::app
