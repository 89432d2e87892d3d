#include "app/report.hpp"

#include "core/atomic_file.hpp"
#include "render/report_html.hpp"
#include "sim/drive_checks.hpp"

#include <cstdio>
#include <string>

namespace vmsim::app {

void write_report(const std::filesystem::path& file, const nlohmann::json& report) {
  core::write_file_atomic(file, report.dump(2) + "\n");
  // Its page for a person, beside it, from the same object (render/report_html.hpp).
  if (file.filename() == "report.json") render::write_report_html(file.parent_path(), report);
}

int print_verdict(const nlohmann::json& report) {
  if (!report.contains("verdict")) return 0;
  if (report.contains("warnings"))
    for (const auto& w : report["warnings"])
      std::fprintf(stderr, "vmsim: %s [%s]: %s\n", w["severity"].get<std::string>().c_str(),
                   w["code"].get<std::string>().c_str(), w["message"].get<std::string>().c_str());
  const std::string verdict = report["verdict"].get<std::string>();
  if (verdict == "invalid")
    std::fprintf(stderr, "vmsim: verdict: invalid - the results are written, but cannot mean what they claim (exit %d)\n",
                 sim::kExitInvalid);
  else if (verdict != "ok")
    std::fprintf(stderr, "vmsim: verdict: %s (report.json lists them)\n", verdict.c_str());
  return verdict == "invalid" ? sim::kExitInvalid : 0;
}

}  // namespace vmsim::app
