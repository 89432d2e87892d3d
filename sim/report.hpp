#pragma once
// report.json's common part: every command on a job starts its report here.
#include "core/job.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace vmsim::sim {

// {"vmsim": version, "command": ..., "job": name, "inputs": {job, machine, program (a curve job: nurbs_control_points,
// nurbs_knots), tool_table, feed_plan: {path, sha256}}}
nlohmann::json report_header(const std::string& command, const core::Job& job);

// vmsim's version string ("0.1.0").
const char* version();

}  // namespace vmsim::sim
