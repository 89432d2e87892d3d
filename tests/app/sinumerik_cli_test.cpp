// vmsim canon and vmsim interp on the real NX-posted 840D sl programs of the production data set for five-axis milling
// with changeovers (Zenodo 10.5281/zenodo.15735480, Scientific Data 10.1038/s41597-025-05294-0, CC BY 4.0), read from
// ../shared/data/real (skipped when absent). References: the files themselves (their line 8 holds the first of
// Spinner's M functions, `N80 M9 M50`; `grep` finds 5 such lines per file) and the counts the program tests check.
#include "tests/app/cli_util.hpp"

#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;
using vmsim_test::run_vmsim;
using vmsim_test::TempDir;

fs::path spinner_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "spinner_u5-620_840d"; }

int count_lines(const std::string& s, const std::string& what = "") {
  int n = 0;
  std::size_t a = 0;
  while (a < s.size()) {
    const std::size_t b = s.find('\n', a);
    const std::string line = s.substr(a, b == std::string::npos ? std::string::npos : b - a);
    if (what.empty() || line.find(what) != std::string::npos) ++n;
    if (b == std::string::npos) break;
    a = b + 1;
  }
  return n;
}

TEST(SinumerikCli, CanonReadsTheRealProgramsAndNamesWhatItDoesNotKnow) {
  if (!fs::exists(spinner_dir())) GTEST_SKIP() << spinner_dir() << " is absent (the real CAM programs of ../shared)";
  TempDir tmp;
  const std::string keychain = "'" + (spinner_dir() / "Keychain_Schluesselanhaenger.mpf").string() + "'";
  // Strict: the first machine-maker M function stops it, named with file, line and word, and nothing is printed.
  auto r = run_vmsim("canon " + keychain, tmp);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("Keychain_Schluesselanhaenger.mpf:8: M50:"), std::string::npos) << r.err;
  EXPECT_TRUE(r.out.empty());
  // Lenient: a warning per unknown M function (M50 on line 8, M27 M29 M51 M65 on lines 640-641), the whole listing.
  r = run_vmsim("canon --lenient " + keychain, tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(count_lines(r.err, "vmsim: warning:"), 5) << r.err;
  EXPECT_EQ(count_lines(r.out), 640);
  EXPECT_EQ(count_lines(r.out, "ARC_FEED("), 58);
  EXPECT_EQ(count_lines(r.out, "CHANGE_TOOL("), 3);
  EXPECT_NE(r.out.find("COMMENT(\"interpreter: tool 2 is T=\\\"BOHRER_D3.3_VHM\\\"\")"), std::string::npos);
  // Named M functions: no warning, the same listing.
  const auto named = run_vmsim("canon --no-motion-m 27,29,50,51,65 " + keychain, tmp);
  ASSERT_EQ(named.code, 0) << named.err;
  EXPECT_TRUE(named.err.empty()) << named.err;
  EXPECT_EQ(named.out, r.out);

  // The .txt program: its content says 840D. Read as RS274/NGC it stops at line 3, as it did before this reader.
  const std::string bottle = "'" + (spinner_dir() / "Bottle_opener_Flaschenoeffner.txt").string() + "'";
  r = run_vmsim("canon --no-motion-m 27,29,50,51,65 " + bottle, tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(count_lines(r.out, "ARC_FEED("), 1553);
  r = run_vmsim("canon --dialect rs274ngc " + bottle, tmp);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("Bottle_opener_Flaschenoeffner.txt:3:"), std::string::npos) << r.err;
}

TEST(SinumerikCli, InterpRunsTheThreePlusTwoProgram) {
  if (!fs::exists(spinner_dir())) GTEST_SKIP() << spinner_dir() << " is absent (the real CAM programs of ../shared)";
  TempDir tmp;
  const fs::path job = fs::path(VMSIM_SOURCE_DIR) / "parts" / "spinner_u5_620" / "achskreuz.toml";
  const auto r = run_vmsim("interp '" + job.string() + "' --summary-only", tmp);
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  // every move of the program (TRAORI 3+2 on five faces, SUPA park moves) within the Spinner's travels and limits
  EXPECT_NE(r.out.find("job spinner_achskreuz: 2655 moves"), std::string::npos) << r.out;
}

}  // namespace
