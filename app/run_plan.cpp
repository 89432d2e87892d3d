// vmsim run --plan JOB: the memory model of a run (sim/memory_plan.hpp) printed, and written as plan.json.
#include "app/run_plan.hpp"

#include "app/mpi_session.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "sim/memory_plan.hpp"
#include "sim/time_plan.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <optional>

namespace vmsim::app {

namespace {

std::string gb(const nlohmann::json& bytes) { return fmt::format("{:.3f} GB", bytes.get<double>() / 1e9); }

void print_plan(const core::Job& job, const nlohmann::json& plan) {
  const nlohmann::json &f = plan["field"], &m = plan["motion"], &one = plan["one_process"];
  std::printf("job %s: %s field at %g mm, %.0f rays (%s), %.0f setpoints, %.0f sweeps", job.name.c_str(),
              f["kind"].get<std::string>().c_str(), f["spacing_mm"].get<double>(), f["rays"].get<double>(),
              gb(f["bytes"]).c_str(), m["samples"].get<double>(), m["sweeps"].get<double>());
  if (plan.contains("reference_field"))
    std::printf("; reference: %.0f setpoints, %.0f sweeps", m["reference_samples"].get<double>(),
                m["reference_sweeps"].get<double>());
  std::printf("\none process: %s (field and its copies %s, motion %s, sweeps %s, outputs %s, base %s)\n",
              gb(one["total_bytes"]).c_str(), gb(one["field_bytes"]).c_str(), gb(one["motion_bytes"]).c_str(),
              gb(one["sweep_bytes"]).c_str(), gb(one["output_bytes"]).c_str(), gb(one["base_bytes"]).c_str());
  const nlohmann::json& avail = plan["available_memory"];
  if (!avail["bytes"].is_null())
    std::printf("available on this machine: %s (%s): one process %s\n", gb(avail["bytes"]).c_str(),
                avail["source"].get<std::string>().c_str(),
                one["fits_available_memory"].get<bool>() ? "fits" : "does NOT fit");
  const int ranks = plan["ranks"].get<int>();
  for (const bool tiles_out : {false, true}) {
    const char* key = tiles_out ? "tiles_out" : "gathered";
    if (!plan.contains(key)) continue;
    const nlohmann::json& p = plan[key];
    std::printf("%d rank%s%s: largest rank %s", ranks, ranks > 1 ? "s" : "",
                ranks == 1  ? ""
                : tiles_out ? ", --tiles-out"
                            : ", gathered to rank 0",
                gb(p["largest_rank_bytes"]).c_str());
    if (ranks > 1) std::printf(" (rank %d: %s)", ranks - 1, gb(p["per_rank"].back()["total_bytes"]).c_str());
    std::printf("\n");
  }
  const nlohmann::json& t = plan["time"];
  if (t["removal_cpu_s"].is_null())
    std::printf("time: not predicted (%s)\n", t["not_predicted"].get<std::string>().c_str());
  else
    std::printf("time: removal %.3g s CPU, whole run %.3g s CPU without the pictures (%.3g shadow rays of %.0f sweeps; within about 2x)\n",
                t["removal_cpu_s"].get<double>(), t["run_cpu_s"].get<double>(),
                t["shadow_rays"]["axial_ball"].get<double>() + t["shadow_rays"]["general"].get<double>() +
                    t["shadow_rays"]["bull_nose"].get<double>(),
                t["sweeps"].get<double>());
  if (!plan.contains("advice")) return;
  const nlohmann::json& a = plan["advice"];
  const int ng = a["ranks_gathered"].get<int>(), nt = a["ranks_tiles_out"].get<int>();
  std::printf("advice for %s per rank: ", gb(a["memory_per_rank_bytes"]).c_str());
  if (ng > 0)
    std::printf("%d rank%s gathered; ", ng, ng > 1 ? "s" : "");
  else
    std::printf("no rank count gathers it (rank 0 holds the whole part); ");
  if (nt > 0)
    std::printf("%d ranks with --tiles-out", nt);
  else
    std::printf("no rank count fits with --tiles-out (the motion and sweeps alone: %s)",
                gb(nlohmann::json(one["base_bytes"].get<double>() + one["motion_bytes"].get<double>() +
                                  one["sweep_bytes"].get<double>()))
                    .c_str());
  if (a.contains("one_process_spacing_mm"))
    std::printf("; one process fits at spacing_mm >= %.3g", a["one_process_spacing_mm"].get<double>());
  std::printf("\n");
}

}  // namespace

int run_plan(const core::Job& job, const RunArgs& args) {
  if (mpi_rank() != 0) return 0;  // the plan is one process's arithmetic
  // With --out, DIR is this command's result like any other's (core/output_dir.hpp): locked and checked before the
  // motion is computed, plan.json written in staging and swapped into place whole, replacing an earlier result.
  std::optional<core::OutputDir> out;
  if (args.out_dir) out.emplace(*args.out_dir, "vmsim run --plan");
  TerminalProgress progress(!args.quiet);
  sim::MemoryPlanOptions options;
  options.feed_scale = args.feed_scale.value_or(1.0);
  options.ranks = args.ranks.value_or(mpi_size());
  if (args.memory_per_rank_gb) options.memory_per_rank_bytes = *args.memory_per_rank_gb * 1e9;
  // The run's motions are computed once, for both models (sim/plan_motion.hpp).
  sim::PlannedMotions motions;
  nlohmann::json plan = sim::plan_memory(job, options, progress, &motions);
  plan["time"] = sim::plan_time(job, motions, progress);  // sim/time_plan.hpp
  print_plan(job, plan);
  if (out) {
    write_report(out->path() / "plan.json", plan);
    out->commit();
    std::printf("wrote %s\n", (out->target() / "plan.json").string().c_str());
  }
  return 0;
}

}  // namespace vmsim::app
