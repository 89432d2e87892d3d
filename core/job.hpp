#pragma once
// A job: which machine runs which program with which tool on which stock, and how the NC interpolates.
// Loaded from job.toml; the schema is documented in parts/README.md.
#include "core/machine.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::core {

enum class ToolShape { Ball, Flat, BullNose };

struct ToolSpec {
  ToolShape shape = ToolShape::Ball;
  double diameter_mm = 10.0;
  double corner_radius_mm = 5.0;  // ball: D/2, flat: 0, bull-nose: given
  double flute_length_mm = 20.0;
  double length_mm = 50.0;        // gauge length, spindle nose to tip
};

struct StockSpec {
  enum class Kind { None, Box, Mesh } kind = Kind::None;
  Eigen::Vector3d min_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_mm = Eigen::Vector3d::Zero();
  std::filesystem::path mesh_file;  // Kind::Mesh: binary or ASCII STL
};

struct InterpSpec {
  double period_s = 1e-3;         // Te
  double tolerance_mm = 0.020;    // largest distance of a setpoint from the programmed geometry
};

struct Job {
  std::string name;
  std::filesystem::path file;          // the job file itself
  std::filesystem::path machine_file;
  std::filesystem::path program_file;
  std::optional<std::filesystem::path> tool_table_file;
  std::vector<int> no_motion_mcodes;   // G-code M codes the machine remaps to actions without motion
  Machine machine;
  ToolSpec tool;
  StockSpec stock;
  InterpSpec interp;
};

Job load_job(const std::filesystem::path& path);

}  // namespace vmsim::core
