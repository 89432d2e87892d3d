// vmsim oga under mpirun: the best-fixed-pair search spread over 2 and 3 ranks (3 oversubscribed on 2 cores).
// Reference: the one-process run of the same command; every result file must be identical byte for byte (the ranks
// only share out the pairs' contour errors; the choice is made from all of them, identically, on every rank).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/app/cli_util.hpp"

using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;

namespace fs = std::filesystem;

namespace {

int cli(const std::string& prefix, const std::string& args, const TempDir& tmp, std::string* err) {
  const fs::path out = tmp.path() / "stdout.txt", errf = tmp.path() / "stderr.txt";
  const std::string cmd =
      prefix + " '" + VMSIM_EXE + "' " + args + " >'" + out.string() + "' 2>'" + errf.string() + "'";
  const int status = std::system(cmd.c_str());
  *err = slurp(errf) + slurp(out);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST(OgaMpi, PairSearchOverRanksGivesTheOneProcessFiles) {
  TempDir tmp;
  const fs::path d = tmp.path();
  // The short XZ profile of oga_cli_test (3 m/min, 1.1 s): straight, concave R30, convex R20, straight.
  write_file(d / "short.ngc",
             "G21 G90 G94 G18\nG1 X-12.000000 Z0.000000 F3000\nG2 X5.207293 Z5.425439 I0.000000 K30.000000\n"
             "G3 X28.150351 Z5.425439 I11.471529 K-16.383041\nG1 X33.065263 Z1.983980\nM30\n");
  write_file(d / "short.toml",
             "[job]\nname = \"short\"\nmachine = \"" + std::string(VMSIM_SOURCE_DIR) +
                 "/parts/machines/mikron_ucp710.toml\"\nprogram = \"short.ngc\"\nstart_mm = [-20.0, 0.0, "
                 "0.0]\n\n[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n");
  const std::string args =
      "oga '" + (d / "short.toml").string() + "' --kp-grid 4:1:8 --kf-grid 0:0.25:1 --dk 0.25 --no-render --out ";
  std::string err;
  ASSERT_EQ(cli("", args + "'" + (d / "one").string() + "'", tmp, &err), 0) << err;
  const nlohmann::json one = nlohmann::json::parse(slurp(d / "one" / "report.json"));
  ASSERT_GT(one["best_fixed_pair"]["pairs_evaluated"].get<int>(), 100);  // enough pairs to share out
  for (int np : {2, 3}) {
    const std::string out = "np" + std::to_string(np);
    const std::string mpirun = std::string("'") + VMSIM_MPIEXEC + "' " + VMSIM_MPIEXEC_NUMPROC_FLAG + " " +
                               std::to_string(np) + " --allow-run-as-root --oversubscribe";
    ASSERT_EQ(cli(mpirun, args + "'" + (d / out).string() + "'", tmp, &err), 0) << err;
    const nlohmann::json rep = nlohmann::json::parse(slurp(d / out / "report.json"));
    EXPECT_EQ(rep["mpi_ranks"], np);
    for (const char* f : {"admissible.csv", "gain_schedule.csv", "gain_schedule_c1.csv", "windows.csv", "mse_table.csv",
                          "comparison.csv"})
      EXPECT_EQ(slurp(d / out / f), slurp(d / "one" / f)) << np << " ranks: " << f;
    for (const char* k : {"best_fixed_pair", "c1", "c2", "mse_table", "verification"})
      EXPECT_EQ(rep[k], one[k]) << np << " ranks: " << k;
  }
}

// A rank that stops (the test hook VMSIM_TEST_STOP_RANK=1: rank 1 stops itself with SIGSTOP at its first exchange)
// would hang the pair search: the watchdog (--watchdog-s 3) ends the job naming the rank and the exchange.
TEST(OgaMpi, AStoppedRankIsNamedByTheWatchdog) {
  TempDir tmp;
  const fs::path d = tmp.path();
  write_file(d / "short.ngc",
             "G21 G90 G94 G18\nG1 X-12.000000 Z0.000000 F3000\nG2 X5.207293 Z5.425439 I0.000000 K30.000000\n"
             "G3 X28.150351 Z5.425439 I11.471529 K-16.383041\nG1 X33.065263 Z1.983980\nM30\n");
  write_file(d / "short.toml",
             "[job]\nname = \"short\"\nmachine = \"" + std::string(VMSIM_SOURCE_DIR) +
                 "/parts/machines/mikron_ucp710.toml\"\nprogram = \"short.ngc\"\nstart_mm = [-20.0, 0.0, "
                 "0.0]\n\n[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n");
  const std::string mpirun = std::string("env VMSIM_TEST_STOP_RANK=1 timeout 300 '") + VMSIM_MPIEXEC + "' " +
                             VMSIM_MPIEXEC_NUMPROC_FLAG + " 2 --allow-run-as-root --oversubscribe";
  std::string err;
  const int code = cli(mpirun,
                       "oga '" + (d / "short.toml").string() +
                           "' --kp-grid 4:1:8 --kf-grid 0:0.25:1 --dk 0.25 --no-render --watchdog-s 3 --out '" +
                           (d / "w").string() + "'",
                       tmp, &err);
  EXPECT_NE(code, 0);
  EXPECT_NE(code, 124) << "timed out: the job hung";
  EXPECT_NE(err.find("rank 1 did not reach oga: the exchange"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(d / "w"));
}
