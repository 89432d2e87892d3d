#include "sim/report.hpp"

#include "core/hash.hpp"

#include <filesystem>

namespace vmsim::sim {

namespace {
nlohmann::json input(const std::filesystem::path& p) {
  std::error_code ec;
  const auto abs = std::filesystem::weakly_canonical(p, ec);
  return {{"path", (ec ? p : abs).string()}, {"sha256", core::sha256_file_hex(p)}};
}
}  // namespace

const char* version() { return VMSIM_VERSION; }

nlohmann::json report_header(const std::string& command, const core::Job& job) {
  nlohmann::json inputs = {{"job", input(job.file)}, {"machine", input(job.machine_file)}};
  if (job.program_file.empty() && job.feedplan && job.feedplan->nurbs) {  // a curve job: the curve is the path
    inputs["nurbs_control_points"] = input(job.feedplan->nurbs->control_points);
    inputs["nurbs_knots"] = input(job.feedplan->nurbs->knots);
  } else {
    inputs["program"] = input(job.program_file);
  }
  if (job.tool_table_file) inputs["tool_table"] = input(*job.tool_table_file);
  if (job.feed_plan_file) inputs["feed_plan"] = input(*job.feed_plan_file);
  return {{"vmsim", VMSIM_VERSION}, {"command", command}, {"job", job.name}, {"inputs", inputs}};
}

}  // namespace vmsim::sim
