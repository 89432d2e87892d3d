#include "app/report.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/utf8.hpp"
#include "render/report_html.hpp"
#include "sim/drive_checks.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <string>

namespace vmsim::app {

// One writer for the CLI and the Python module (render/report_html.hpp).
void write_report(const std::filesystem::path& file, const nlohmann::json& report) {
  render::write_report(file, report);
}

nlohmann::json read_report(const std::filesystem::path& dir) {
  const std::filesystem::path file = dir / "report.json";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    throw core::Error(dir.string() +
                      ": no report.json: not a complete result of vmsim (a run that did not finish, or "
                      "another program's directory)");
  std::ifstream in(file);
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw core::Error(file.string() + ": not valid JSON: " + e.what());
  }
}

std::vector<std::string> listed_files(const nlohmann::json& report) {
  std::vector<std::string> names;
  if (report.contains("files") && report["files"].is_array())
    for (const auto& f : report["files"])
      if (f.is_string()) names.push_back(f.get<std::string>());
  return names;
}

void require_utf8_input(const std::filesystem::path& file, const char* what) {
  std::error_code ec;
  const std::filesystem::path full = std::filesystem::absolute(file, ec);
  core::require_utf8_path(ec ? file : full, what);
}

void require_listed_in_report(const std::filesystem::path& file) {
  const std::filesystem::path dir = file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path();
  std::error_code ec;
  const bool has_report = std::filesystem::exists(dir / "report.json", ec);
  if (!has_report && !std::filesystem::exists(dir / core::kOutputMarker, ec)) return;  // not vmsim's directory
  const std::vector<std::string> names = listed_files(read_report(dir));
  const std::string name = file.filename().string();
  if (std::find(names.begin(), names.end(), name) == names.end())
    throw core::Error(file.string() + ": not listed in " + (dir / "report.json").string() +
                      " (\"files\"): a file an earlier run left in that directory, not a result of the run it reports");
}

std::filesystem::path out_dir_or_default(const std::optional<std::filesystem::path>& out_dir, const std::string& name,
                                         const char* command) {
  if (out_dir) return *out_dir;
  std::string dir = (name.empty() ? std::string("vmsim") : name) + "_" + command;
  for (char& c : dir)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != '_') c = '_';
  return std::filesystem::current_path() / dir;
}

int print_verdict(const nlohmann::json& report) {
  if (!report.contains("verdict")) return 0;
  if (report.contains("warnings"))
    for (const auto& w : report["warnings"])
      std::fprintf(stderr, "vmsim: %s [%s]: %s\n", w["severity"].get<std::string>().c_str(),
                   w["code"].get<std::string>().c_str(), w["message"].get<std::string>().c_str());
  const std::string verdict = report["verdict"].get<std::string>();
  if (verdict == "invalid")
    std::fprintf(stderr,
                 "vmsim: verdict: invalid - the results are written, but cannot mean what they claim (exit %d)\n",
                 sim::kExitInvalid);
  else if (verdict != "ok")
    std::fprintf(stderr, "vmsim: verdict: %s (report.json lists them)\n", verdict.c_str());
  return verdict == "invalid" ? sim::kExitInvalid : 0;
}

}  // namespace vmsim::app
