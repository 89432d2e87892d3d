#pragma once
// vmsim oga as a library call: offline gain adjustment (Duong et al.) on a job's biaxial profile. The job's program is
// interpolated by the job's chain (sim::Chain: as vmsim run and vmsim motion interpolate it, its feed plan included),
// so the gain schedule found here is the one those commands accept through [job] gain_schedule. The command line
// writes the results to files and draws them; the Python module hands them over as arrays.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "core/toolpath.hpp"
#include "methods/oga.hpp"
#include "motion/interp.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <utility>

namespace vmsim::sim {

struct OgaJobOptions {
  // The search's options (grids, per-axis ranges, dK, f, C1, windows, lead-in, settling, Task 2's start, the share of
  // the pair search under MPI). Its row_weight and progress are set by oga_job.
  methods::OgaOptions search;
  // A Kp range ((m/min)/mm) for every axis the profile moves that search.range does not name.
  std::optional<std::pair<double, double>> range_all;
  // Verify the schedule on the whole path (the nonlinear model; under MPI only rank 0 does).
  bool verify = true;
};

struct OgaJobResult {
  core::ToolPath program;       // workpiece frame
  motion::InterpResult interp;  // the setpoints the gains are for
  methods::OgaOptions options;  // as run: the row weights and the ranges of every adjusted axis
  methods::OgaResult result;
  std::optional<methods::OgaVerification> verification;
  double verification_s = 0;
  // report.json's figures once verified: interpolation, options, admissible, best_fixed_pair, c1, c2, mse_table,
  // windows, verification, limits_held, advice; and search timings (timings_s's search_*).
  nlohmann::json report, timings;
  // MSE(CE) change of C2 against C1 (%), and the windows with a note (every candidate of an axis broke a limit).
  double change_percent = 0;
  int windows_with_note = 0;
};

// Throws core::Error naming the job file for a program without a feed move, and as methods::offline_gain_adjustment
// for profiles OGA does not handle. The chain runs the drives' own gains (OGA computes the schedule).
OgaJobResult oga_job(const core::Job& job, const OgaJobOptions& options,
                     core::Progress& progress = core::no_progress());

}  // namespace vmsim::sim
