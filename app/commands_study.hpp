#pragma once
// vmsim study: a job's variations run one by one, or spread over MPI ranks (mpirun -np N vmsim study ...).
#include <filesystem>
#include <string>

namespace vmsim::app {

struct StudyArgs {
  std::filesystem::path study;    // the study file (parts/README.md, "Study file")
  std::filesystem::path out_dir;  // results.csv, study.json, variations/NNN/ (each variation's vmsim run output)
  std::string keep = "all";       // all: every variation's files; summary: its job, machine, report.json, run.log
  bool quiet = false;             // no line per finished variation on stdout
};
// Rank 0 reads the study and hands out variations one at a time to whichever rank asks (and works through the queue
// itself too); every rank runs its variations through vmsim run's pipeline. A variation that fails is a row with
// its message; the others' results stay. Returns 0 once the table is written (failed variations included).
int run_study(const StudyArgs& args);

}  // namespace vmsim::app
