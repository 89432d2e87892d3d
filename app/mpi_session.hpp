#pragma once
// MPI for vmsim's scale-out commands (tiled `vmsim run`, `vmsim study`). MPI is initialised only when the
// process was started by an MPI launcher (mpirun/mpiexec/srun), so a plain `vmsim ...` never pays MPI's start-up
// nor needs a launcher; every other command behaves as one process (rank 0 of 1).
#include <string>

namespace vmsim::app {

// Call first in main. Initialises MPI (MPI_THREAD_FUNNELED: OpenMP threads never call MPI) when a launcher's
// environment is present; otherwise does nothing.
void mpi_start(int* argc, char*** argv);

// Call once at exit (MPI_Finalize when started). Safe when MPI was never started.
void mpi_finish();

// Ends every rank at once with this exit code (MPI_Abort) when running on more than one rank, so an error on one
// rank can never leave the others waiting in a collective; otherwise returns and the caller exits normally.
void mpi_abort_all(int exit_code);

// Rank 0's string on every rank (a collective: every rank calls it); the string itself without MPI.
std::string mpi_broadcast(const std::string& from_rank0);

// The watchdog's limit (s) at the ranks' exchanges (app/tiled_run.hpp quiet_barrier): the command's --watchdog-s
// (set_watchdog_seconds), else the environment variable VMSIM_WATCHDOG_S, else 3600. Throws core::Error on a value
// that is not a positive number of seconds.
double watchdog_seconds();
void set_watchdog_seconds(double seconds);

bool mpi_active();  // MPI was started and the world has more than one rank
int mpi_rank();     // 0 without MPI
int mpi_size();     // 1 without MPI

// While one lives, on its thread, mpi_active() is false, mpi_rank() 0 and mpi_size() 1: a command run inside it (vmsim
// study runs each variation through vmsim run on one rank, rank 0's on a second thread) behaves as one process and
// never enters a collective the other ranks are not in.
class MpiSingleProcess {
 public:
  MpiSingleProcess();
  ~MpiSingleProcess();
  MpiSingleProcess(const MpiSingleProcess&) = delete;
  MpiSingleProcess& operator=(const MpiSingleProcess&) = delete;

 private:
  bool previous_;
};

}  // namespace vmsim::app
