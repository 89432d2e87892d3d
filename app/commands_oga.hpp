#pragma once
// vmsim oga: offline gain adjustment (Duong et al.) as a command. Its own header so that app/commands.hpp is not
// touched.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

struct OgaArgs {
  std::filesystem::path job;                     // a biaxial job (two of X Y Z move)
  std::optional<std::filesystem::path> out_dir;  // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  std::string kp_grid = "1:0.5:9";               // MIN:STEP:MAX, (m/min)/mm (Duong et al. section III.D)
  std::string kf_grid = "0:0.1:1.2";             // MIN:STEP:MAX
  std::vector<std::string> ranges;               // "MIN:MAX" (every adjusted axis) or "AXIS=MIN:MAX", repeatable
  double gain_step = 0.03;                       // dK, (m/min)/mm
  double frequency_hz = 10.0;                    // f of eq. 3's sinusoid
  std::string reference = "best";                // C1: "best" (the best admissible fixed pair) or "machine"
  double straight_curvature_per_mm = 1e-4;       // window options (methods::WindowOptions)
  double transition_rate_per_mm2 = 0.01;
  long long min_window_rows = 3;
  long long lead_in_rows = 100;
  double settle_s = 0.2;
  bool from_start = false;     // Task 2 as Duong et al.: every candidate from the first instant
  std::string limits = "all";  // the limits that judge admissibility (methods::parse_limit_set)
  std::optional<int> threads;  // OpenMP threads (default: OpenMP's own)
  bool no_render = false;      // no charts
  std::string image_size = "1600x900";
};

// vmsim oga JOB: admissible gains per axis, the best fixed pair (C1), the gain schedule (C2) by receding windows,
// its verification through the whole-path simulation, report.json and charts.
int run_oga(const OgaArgs& args);

}  // namespace vmsim::app
