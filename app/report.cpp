#include "app/report.hpp"

#include "core/atomic_file.hpp"
#include "core/sha256.hpp"
#include "render/report_html.hpp"

namespace vmsim::app {

namespace {
nlohmann::json input(const std::filesystem::path& p) {
  std::error_code ec;
  const auto abs = std::filesystem::weakly_canonical(p, ec);
  return {{"path", (ec ? p : abs).string()}, {"sha256", core::sha256_file_hex(p)}};
}
}  // namespace

nlohmann::json report_header(const std::string& command, const core::Job& job) {
  nlohmann::json inputs = {{"job", input(job.file)}, {"machine", input(job.machine_file)}, {"program", input(job.program_file)}};
  if (job.tool_table_file) inputs["tool_table"] = input(*job.tool_table_file);
  return {{"vmsim", VMSIM_VERSION}, {"command", command}, {"job", job.name}, {"inputs", inputs}};
}

void write_report(const std::filesystem::path& file, const nlohmann::json& report) {
  core::write_file_atomic(file, report.dump(2) + "\n");
  // Its page for a person, beside it, from the same object (render/report_html.hpp).
  if (file.filename() == "report.json") render::write_report_html(file.parent_path(), report);
}

}  // namespace vmsim::app
