#include "app/mpi_session.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <mpi.h>

#include <cmath>
#include <cstdlib>
#include <string>

namespace vmsim::app {
namespace {
bool g_started = false;
int g_rank = 0;
int g_size = 1;
thread_local bool t_single = false;
double g_watchdog_option_s = 0;  // --watchdog-s; 0: not given  // inside an MpiSingleProcess on this thread

// The launchers' own markers: Open MPI's mpirun, PMI-1/2 (MPICH's hydra, Slurm's srun) and PMIx.
bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(v) != nullptr) return true;
  return false;
}
}  // namespace

void mpi_start(int* argc, char*** argv) {
  if (g_started || !launched_by_mpi()) return;
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  g_started = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &g_size);
}

void mpi_finish() {
  if (!g_started) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
  g_started = false;
}

void mpi_abort_all(int exit_code) {
  if (g_started && g_size > 1) MPI_Abort(MPI_COMM_WORLD, exit_code);
}

std::string mpi_broadcast(const std::string& from_rank0) {
  if (!mpi_active()) return from_rank0;
  std::string s = from_rank0;
  int n = static_cast<int>(s.size());
  MPI_Bcast(&n, 1, MPI_INT, 0, MPI_COMM_WORLD);
  s.resize(static_cast<std::size_t>(n));
  MPI_Bcast(s.data(), n, MPI_CHAR, 0, MPI_COMM_WORLD);
  return s;
}

double watchdog_seconds() {
  if (g_watchdog_option_s > 0) return g_watchdog_option_s;
  const char* v = std::getenv("VMSIM_WATCHDOG_S");
  if (!v || !*v) return 3600.0;
  char* end = nullptr;
  const double s = std::strtod(v, &end);
  if (end == v || *end != '\0' || !(s > 0) || !std::isfinite(s))
    throw core::Error(fmt::format("VMSIM_WATCHDOG_S: expected a positive number of seconds, found \"{}\"", v));
  return s;
}

void set_watchdog_seconds(double seconds) {
  if (!(seconds > 0) || !std::isfinite(seconds))
    throw core::Error(fmt::format("--watchdog-s: expected a positive number of seconds, found {}", seconds));
  g_watchdog_option_s = seconds;
}

bool mpi_active() { return !t_single && g_started && g_size > 1; }
int mpi_rank() { return t_single ? 0 : g_rank; }
int mpi_size() { return t_single ? 1 : g_size; }

MpiSingleProcess::MpiSingleProcess() : previous_(t_single) { t_single = true; }
MpiSingleProcess::~MpiSingleProcess() { t_single = previous_; }

}  // namespace vmsim::app
