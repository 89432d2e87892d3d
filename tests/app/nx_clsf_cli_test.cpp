// vmsim interp, run and canon on the real NX CLSF files of the MECH491 post-processor course project (CC0), read from
// ../shared/data/real (skipped when absent), on the HAAS UMC-750-like machine. References: the files themselves (347
// moves of APT_Variable_Axis.txt: 348 GOTO/s, the first the start; its TLDATA/ on line 2 a D1.00 in ball) and issue
// 24's rule that units are never guessed silently.
#include "tests/app/cli_util.hpp"

#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;
using vmsim_test::run_vmsim;
using vmsim_test::TempDir;
using vmsim_test::write_file;

fs::path nx_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "nx_clsf_haas_umc750"; }

TEST(NxClsfCli, InterpRunsTheVariableAxisFileOnTheHaas) {
  if (!fs::exists(nx_dir())) GTEST_SKIP() << nx_dir() << " is absent (the real CAM programs of ../shared)";
  TempDir tmp;
  const fs::path job = fs::path(VMSIM_SOURCE_DIR) / "parts" / "haas_umc750" / "variable_axis.toml";
  const auto r = run_vmsim("interp '" + job.string() + "' --summary-only", tmp);
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("job haas_variable_axis: 347 moves"), std::string::npos) << r.out;
  EXPECT_TRUE(r.err.find("warning") == std::string::npos) << r.err;
  // canon is for G-code and 840D programs: it says so for a CLSF (found by content, though it is a .txt).
  const auto c = run_vmsim("canon '" + (nx_dir() / "APT_code.txt").string() + "'", tmp);
  EXPECT_NE(c.code, 0);
  EXPECT_NE(c.err.find("not APT CL files"), std::string::npos) << c.err;
}

TEST(NxClsfCli, RunWarnsOfMissingUnitsAndSaysWhichToolCuts) {
  if (!fs::exists(nx_dir())) GTEST_SKIP() << nx_dir() << " is absent (the real CAM programs of ../shared)";
  TempDir tmp;
  // No program_units and no [tool]: the file is read as mm (a warning), its TLDATA/ ball cuts (said on stderr).
  const fs::path job = tmp.path() / "bare.toml";
  write_file(job,
             "[job]\nmachine = '" + (fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines" / "haas_umc750.toml").string() +
                 "'\nprogram = '" + (nx_dir() / "APT_Variable_Axis.txt").string() +
                 "'\n[stock]\ntype = \"box\"\nmin_mm = [-5.0, -4.0, 0.0]\nmax_mm = [4.0, 4.0, 1.25]\n"
                 "[removal]\nfield = \"zmap\"\nspacing_mm = 0.25\nmotion = \"program\"\ntrack_tolerance_mm = 0.01\n"
                 "[reference]\nkind = \"none\"\n");
  const auto r =
      run_vmsim("run '" + job.string() + "' --no-render --quiet --out '" + (tmp.path() / "out").string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_NE(r.err.find("vmsim: warning: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no UNITS/ record and no [job] program_units"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("tool: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("APT_Variable_Axis.txt:2: the job has no [tool]: the program's ball D1 R0.5 mm"),
            std::string::npos)
      << r.err;
  const nlohmann::json report = vmsim_test::read_json(tmp.path() / "out" / "report.json");
  // report.json says the program's own tool cut (issue 24: on stderr and in the report).
  ASSERT_TRUE(report.contains("tools")) << report.dump();
  EXPECT_NE(report["tools"]["source"].get<std::string>().find("APT_Variable_Axis.txt:2"), std::string::npos)
      << report["tools"].dump();
  EXPECT_EQ(report["tools"]["list"][0]["type"], "ball");
  EXPECT_DOUBLE_EQ(report["tools"]["list"][0]["diameter_mm"].get<double>(), 1.0);  // read as mm (no UNITS/)
  ASSERT_TRUE(report.contains("program_warnings"));
  EXPECT_EQ(report["program_warnings"].size(), 1u);
}

}  // namespace
