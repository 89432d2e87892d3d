// Issue 18 from the command line: a run whose drives cannot follow ends with the verdict "invalid" in report.json,
// its findings on stderr and exit code 4 (README, "What you can rely on"); an unstable drive and a program that
// would need more setpoints than allowed are refused before any work, with the key to change; a healthy job's
// verdict is "ok".
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

namespace {

using vmsim_test::CliRun;
using vmsim_test::read_json;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;
namespace fs = std::filesystem;

using vmsim::test::kSourceDir;

// The Mikron machine file with the first occurrence of `key = ...` (the X axis' drive) replaced.
fs::path machine_with(const TempDir& tmp, const std::string& key, const std::string& value) {
  std::string text = slurp(kSourceDir + "/parts/machines/mikron_ucp710.toml");
  const std::regex re("\n" + key + " = [^\n#]*");
  const std::string changed =
      std::regex_replace(text, re, "\n" + key + " = " + value, std::regex_constants::format_first_only);
  EXPECT_NE(changed, text) << key;
  const fs::path m = tmp.path() / "machine.toml";
  write_file(m, changed);
  return m;
}

// A 60 mm pass along X at 2 m/min over a box stock (z-map), on `machine`.
fs::path job_on(const TempDir& tmp, const fs::path& machine, const std::string& program = "") {
  write_file(tmp.path() / "pass.ngc",
             program.empty() ? "G21 G90 G94\nG0 X0 Y5 Z5\nG1 Z-0.5 F500\nG1 X60 F2000\nG0 Z5\nM2\n" : program);
  const fs::path job = tmp.path() / "job.toml";
  write_file(job, "[job]\nname = \"pass\"\nmachine = \"" + machine.string() +
                      "\"\nprogram = \"pass.ngc\"\n[tool]\ntype = \"ball\"\ndiameter_mm = 6.0\n"
                      "[stock]\ntype = \"box\"\nmin_mm = [-5.0, 0.0, -3.0]\nmax_mm = [65.0, 10.0, 0.0]\n"
                      "[removal]\nspacing_mm = 0.2\n[reference]\nkind = \"program\"\n");
  return job;
}

// Reference: current_limit_A = 0.001 A (a unit slip for 30 A) gives the X motor 1.5 mN m against 1.5 N m of Coulomb
// friction: it never breaks loose, so the axis stays where it started while its setpoints travel 60 mm. Before
// issue 18 this exited 0 with "marks: none" and "limits held: currents yes".
TEST(ChecksCli, AnAxisThatCannotFollowIsInvalid) {
  TempDir tmp;
  const fs::path job = job_on(tmp, machine_with(tmp, "current_limit_A", "0.001"));
  const CliRun m = run_vmsim("motion '" + job.string() + "' --out '" + (tmp.path() / "m").string() + "'", tmp);
  EXPECT_EQ(m.code, 4) << m.err;
  EXPECT_NE(m.err.find("following_error_implausible"), std::string::npos) << m.err;
  EXPECT_NE(m.err.find("current_limit_A"), std::string::npos) << m.err;
  const nlohmann::json rm = read_json(tmp.path() / "m" / "report.json");
  EXPECT_EQ(rm["verdict"], "invalid");
  EXPECT_FALSE(rm["limits_held"]["currents"].get<bool>());
  bool found = false;
  for (const auto& w : rm["warnings"])
    if (w["code"] == "following_error_implausible" && w["subject"] == "X") found = true;
  EXPECT_TRUE(found) << rm["warnings"].dump();
  // The axis' following error is the whole pass, far beyond its bound.
  EXPECT_GT(rm["drive_checks"]["X"]["following_error_max_mm"].get<double>(), 50.0);

  const CliRun r =
      run_vmsim("run '" + job.string() + "' --quiet --no-render --out '" + (tmp.path() / "r").string() + "'", tmp);
  EXPECT_EQ(r.code, 4) << r.err;
  const nlohmann::json rr = read_json(tmp.path() / "r" / "report.json");
  EXPECT_EQ(rr["verdict"], "invalid");
  EXPECT_TRUE(fs::exists(tmp.path() / "r" / "surface.x3p"));  // the results are written, and marked
}

// The same job on the unchanged machine: no finding, exit 0.
TEST(ChecksCli, AHealthyJobIsOk) {
  TempDir tmp;
  const fs::path job = job_on(tmp, kSourceDir + "/parts/machines/mikron_ucp710.toml");
  const CliRun m = run_vmsim("motion '" + job.string() + "' --out '" + (tmp.path() / "m").string() + "'", tmp);
  EXPECT_EQ(m.code, 0) << m.err;
  const nlohmann::json rm = read_json(tmp.path() / "m" / "report.json");
  EXPECT_EQ(rm["verdict"], "ok") << rm["warnings"].dump();
  EXPECT_TRUE(rm["warnings"].empty());
  EXPECT_TRUE(rm["limits_held"]["currents"].get<bool>());
}

// kv_1000_per_min = 6000 for 6: the position loop is unstable; refused before the drives run, naming the key.
TEST(ChecksCli, AnUnstableDriveIsRefused) {
  TempDir tmp;
  const fs::path job = job_on(tmp, machine_with(tmp, "kv_1000_per_min", "6000.0"));
  const CliRun m = run_vmsim("motion '" + job.string() + "' --out '" + (tmp.path() / "m").string() + "'", tmp);
  EXPECT_EQ(m.code, 2) << m.err;
  EXPECT_NE(m.err.find("position loop is unstable"), std::string::npos) << m.err;
  EXPECT_NE(m.err.find("kv_1000_per_min"), std::string::npos) << m.err;
  EXPECT_EQ(m.err.find("internal error"), std::string::npos) << m.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "m" / "report.json"));

  TempDir tmp2;
  const fs::path job2 = job_on(tmp2, machine_with(tmp2, "inertia_kg_m2", "1e-9"));
  const CliRun r =
      run_vmsim("run '" + job2.string() + "' --quiet --no-render --out '" + (tmp2.path() / "r").string() + "'", tmp2);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("inertia_kg_m2"), std::string::npos) << r.err;
}

// A typo F0.01 (mm/min) in a 3-line program: 60 mm at 0.01 mm/min is 100 hours, 3.6e8 setpoints. Before issue 18 the
// interpolator allocated them and died with "internal error: std::bad_alloc", in `vmsim run --plan` too.
TEST(ChecksCli, ATinyFeedIsRefusedBeforeInterpolating) {
  TempDir tmp;
  const fs::path job =
      job_on(tmp, kSourceDir + "/parts/machines/mikron_ucp710.toml", "G21 G90 G94\nG1 X60 F0.01\nM2\n");
  for (const std::string cmd : {"interp", "motion", "run --plan"}) {
    const CliRun r = run_vmsim(cmd + " '" + job.string() + "' --out '" + (tmp.path() / "o").string() + "'", tmp);
    EXPECT_EQ(r.code, 2) << cmd << ": " << r.err;
    EXPECT_NE(r.err.find("max_setpoints"), std::string::npos) << cmd << ": " << r.err;
    EXPECT_NE(r.err.find("at least 3.6e+08 setpoints"), std::string::npos) << cmd << ": " << r.err;
    EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos) << cmd << ": " << r.err;
  }
  // Raising the key past the estimate lets the memory guard speak instead (3.6e8 setpoints need > 100 GB).
  std::string text = slurp(job);
  write_file(job, text + "[interpolation]\nmax_setpoints = 1e12\n");
  const CliRun r = run_vmsim("interp '" + job.string() + "' --out '" + (tmp.path() / "o").string() + "'", tmp);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("is available"), std::string::npos) << r.err;
}

// period_ms = 0.001 (us typed as ms): refused at once because it does not fit the drives' loops (125 us, 62.5 us),
// not after minutes of interpolating millions of setpoints.
TEST(ChecksCli, AMicrosecondPeriodIsRefusedBeforeInterpolating) {
  TempDir tmp;
  const fs::path job = job_on(tmp, kSourceDir + "/parts/machines/mikron_ucp710.toml");
  write_file(job, slurp(job) + "[interpolation]\nperiod_ms = 0.001\n");
  for (const std::string cmd : {"interp", "motion"}) {
    const CliRun r =
        run_vmsim(cmd + " '" + job.string() + "' --out '" + (tmp.path() / "o").string() + "'", tmp, "timeout 60 ");
    EXPECT_EQ(r.code, 2) << cmd << ": " << r.err;
    EXPECT_NE(r.err.find("period_ms = 0.001 does not fit the drive of axis"), std::string::npos) << r.err;
  }
}

// The kernel's MemAvailable (bytes), for the memory guards' tests; infinity when unknown.
double mem_available_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kb = 0;
  std::string unit;
  while (in >> key >> kb >> unit)
    if (key == "MemAvailable:") return kb * 1024;
  return INFINITY;
}

// A z-map at 0.01 mm over a 190 x 190 mm stock: 3.6e8 rays, under the fixed ray limit (4e8) but, with the stock copy
// and the outputs (sim/memory_plan.hpp's model: 16 B per ray, 136 B per node), 55 GB. Before issue 18 the run
// started and died; now it is refused before the stock is made, naming the estimate, the memory and the key.
TEST(ChecksCli, AFieldBeyondTheAvailableMemoryIsRefused) {
  if (mem_available_bytes() > 50e9) GTEST_SKIP() << "this machine has more than 50 GB available";
  TempDir tmp;
  const fs::path job = job_on(tmp, kSourceDir + "/parts/machines/mikron_ucp710.toml");
  std::string text = slurp(job);
  text = std::regex_replace(text, std::regex("max_mm = \\[65.0, 10.0, 0.0\\]"), "max_mm = [185.0, 190.0, 0.0]");
  text = std::regex_replace(text, std::regex("spacing_mm = 0.2"), "spacing_mm = 0.01");
  write_file(job, text);
  const CliRun r =
      run_vmsim("run '" + job.string() + "' --quiet --no-render --out '" + (tmp.path() / "r").string() + "'", tmp);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("spacing_mm = 0.01"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("is available"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos) << r.err;
}

// STL stocks without triangles (an empty binary STL, an ASCII `solid x`/`endsolid x`) crashed vmsim run (the bounding
// box was taken before the closedness check); a mesh whose facets all bound no area gave an error naming neither the
// file nor the cause. All three are refused naming the file and the cause.
TEST(ChecksCli, StlStocksWithoutTrianglesAreRefused) {
  TempDir tmp;
  const fs::path job = job_on(tmp, kSourceDir + "/parts/machines/mikron_ucp710.toml");
  std::string text = slurp(job);
  text = std::regex_replace(text, std::regex("type = \"box\"\nmin_mm = [^\n]*\nmax_mm = [^\n]*"),
                            "type = \"stl\"\nfile = \"stock.stl\"");
  write_file(job, text);
  std::string empty_binary(80, ' ');
  empty_binary += std::string(4, '\0');
  // Two facets whose corners all coincide: each has a repeated vertex once welded.
  std::string degenerate = "solid d\n";
  for (int k = 0; k < 2; ++k)
    degenerate += "facet normal 0 0 1\nouter loop\nvertex 1 1 1\nvertex 1 1 1\nvertex 1 1 1\nendloop\nendfacet\n";
  degenerate += "endsolid d\n";
  for (const auto& [stl, cause] : std::vector<std::pair<std::string, std::string>>{
           {empty_binary, "no triangles"}, {"solid x\nendsolid x\n", "no triangles"}, {degenerate, "no area"}}) {
    write_file(tmp.path() / "stock.stl", stl);
    const CliRun r =
        run_vmsim("run '" + job.string() + "' --quiet --no-render --out '" + (tmp.path() / "r").string() + "'", tmp);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("stock.stl"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(cause), std::string::npos) << r.err;
  }
}

// A surface path that is a FIFO blocked vmsim compare forever; every reader now refuses a non-regular file.
TEST(ChecksCli, AFifoIsRefusedNotReadForever) {
  TempDir tmp;
  const fs::path fifo = tmp.path() / "scan.x3p";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // timeout: a regression would hang; 124 is timeout's exit code.
  const CliRun r = run_vmsim("stats '" + fifo.string() + "'", tmp, "timeout 60 ");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("FIFO"), std::string::npos) << r.err;
}

// --plan holds its memory model against this machine's available memory (core/memory.hpp): a small job fits.
TEST(ChecksCli, ThePlanComparesWithTheAvailableMemory) {
  TempDir tmp;
  const fs::path job = job_on(tmp, kSourceDir + "/parts/machines/mikron_ucp710.toml");
  const CliRun r = run_vmsim("run '" + job.string() + "' --plan --out '" + (tmp.path() / "p").string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("available on this machine"), std::string::npos) << r.out;
  const nlohmann::json plan = read_json(tmp.path() / "p" / "plan.json");
  EXPECT_GT(plan["available_memory"]["bytes"].get<double>(), plan["one_process"]["total_bytes"].get<double>());
  EXPECT_TRUE(plan["one_process"]["fits_available_memory"].get<bool>());
}

}  // namespace
