#pragma once
// report.html: a result directory's report.json as one page a person opens in a browser (from a file manager, or a
// folder attached to an e-mail). Generated from the same JSON object and the pictures present in the directory,
// never from figures typed twice. Self-contained: no script, no network; pictures by relative links inside the
// directory. Valid HTML5, readable at phone width, printable (print CSS).
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace vmsim::render {

// The page for `report` (a report.json object: its "command" picks the sections; a study's study.json too) whose
// files lie in `dir` (pictures in dir/images are linked when they are readable PNG files). Every key of the report
// that no section shows is listed under "All figures", so nothing in report.json is hidden. Every string from the
// report is escaped.
std::string report_html(const nlohmann::json& report, const std::filesystem::path& dir);

// Writes report_html(report, dir) to dir/report.html, atomically. Throws core::Error on an I/O error.
void write_report_html(const std::filesystem::path& dir, const nlohmann::json& report);

// report.json (or another report file): written atomically, pretty-printed; a report.json gets its report.html
// beside it, from the same object. The CLI (app/report.hpp) and the Python module write reports through it.
void write_report(const std::filesystem::path& file, const nlohmann::json& report);

}  // namespace vmsim::render
