// vmsim study, end to end as a user runs it, without MPI and under mpirun -np 2 and -np 3 (oversubscribed).
// Reference: each variation run on its own by a separate `vmsim run` invocation, on job and machine files this test
// writes by editing the base files' text (not through the study's override code), with the feed scale on the command
// line; the study's table must hold exactly the figures of those runs' report.json, whatever the number of ranks.
// Also: a failing variation is a row with its message and the others are kept; bad study files are errors naming
// the file and the key. The base job is the plane-cylinder pass of the feed-drive simulation paper on a coarse 0.25 mm
// z-map.
#include "sim/study.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

using vmsim_test::CliRun;
using vmsim_test::read_json;
using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;

namespace {

// `prefix` goes before the vmsim executable (mpirun and its options); the command runs in `cwd`.
CliRun study_cli(const std::string& prefix, const std::string& args, const fs::path& cwd, const TempDir& tmp) {
  return vmsim_test::run_vmsim(args, tmp, "cd '" + cwd.string() + "' && " + prefix + " ");
}

// mpirun as the tests of STACK.md run it (as root here; -np above the cores needs --oversubscribe, P9).
std::string fmt_mpirun(int np) {
  return std::string("'") + VMSIM_MPIEXEC + "' " + VMSIM_MPIEXEC_NUMPROC_FLAG + " " + std::to_string(np) +
         " --allow-run-as-root --oversubscribe";
}

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream f(p, std::ios::binary);
  f << text;
}

// RFC 4180 CSV: a header and rows of cells, by column name.
struct Table {
  std::vector<std::string> names;
  std::vector<std::vector<std::string>> rows;
  std::string at(std::size_t row, const std::string& col) const {
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == col) return rows.at(row).at(i);
    ADD_FAILURE() << "no column " << col;
    return {};
  }
};
Table read_table(const fs::path& p) {
  const std::string s = slurp(p);
  Table t;
  std::vector<std::string> row;
  std::string cell;
  bool quoted = false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (quoted) {
      if (c == '"' && i + 1 < s.size() && s[i + 1] == '"')
        cell += '"', ++i;
      else if (c == '"')
        quoted = false;
      else
        cell += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      row.push_back(cell), cell.clear();
    } else if (c == '\n') {
      row.push_back(cell), cell.clear();
      if (t.names.empty())
        t.names = row;
      else
        t.rows.push_back(row);
      row.clear();
    } else {
      cell += c;
    }
  }
  return t;
}

double num(const std::string& s) {
  EXPECT_FALSE(s.empty());
  return std::strtod(s.c_str(), nullptr);
}

using vmsim::test::kPartsPath;

const char* kBaseJob = R"([job]
name = "study_base"
machine = "../machines/mikron.toml"
program = "pass.ngc"
tool_table = "tools.tbl"
start_mm = [-8.0, 5.0, 40.0]

[tool]
type = "ball"
diameter_mm = 10.0
flute_length_mm = 25.0
length_mm = 50.0

[stock]
type = "stl"
file = "stock.stl"

[interpolation]
period_ms = 1.0
tolerance_mm = 0.020

[removal]
field = "zmap"
spacing_mm = 0.25
motion = "actual"

[reference]
kind = "program"
)";

// The layout a user has: the base job beside its program, tool table and stock, the machine one folder up, the
// study in another folder; everything relative.
void make_layout(const fs::path& root) {
  fs::create_directories(root / "part");
  fs::create_directories(root / "machines");
  fs::copy_file(kPartsPath / "plane_cylinder" / "plane_cylinder_fast.ngc", root / "part" / "pass.ngc");
  fs::copy_file(kPartsPath / "plane_cylinder" / "tools.tbl", root / "part" / "tools.tbl");
  fs::copy_file(kPartsPath / "plane_cylinder" / "plane_cylinder_stock.stl", root / "part" / "stock.stl");
  fs::copy_file(kPartsPath / "machines" / "mikron_ucp710.toml", root / "machines" / "mikron.toml");
  write(root / "part" / "job.toml", kBaseJob);
}

// Text edits for the reference runs: the line starting with `key =` after `after` (the first match) gets `value`.
std::string replace_line(const std::string& text, const std::string& after, const std::string& key,
                         const std::string& value) {
  const std::size_t from = text.find(after);
  EXPECT_NE(from, std::string::npos) << after;
  const std::size_t at = text.find("\n" + key + " =", from);
  EXPECT_NE(at, std::string::npos) << key;
  const std::size_t end = text.find('\n', at + 1);
  return text.substr(0, at + 1) + key + " = " + value + text.substr(end);
}

struct Figures {
  std::optional<double> depth, dev_min, dev_max, ce_max, ce_rms, cycle;
  int marks = 0;
};
// From a vmsim run report.json, read here on its own (the deepest mark is the largest depth_mm of "marks").
Figures figures_of(const nlohmann::json& r) {
  Figures f;
  for (const auto& m : r.at("marks")) {
    ++f.marks;
    const double d = m.at("depth_mm").get<double>();
    if (!f.depth || d > *f.depth) f.depth = d;
  }
  if (r["surface"].contains("deviation_min_mm")) f.dev_min = r["surface"]["deviation_min_mm"].get<double>();
  if (r["surface"].contains("deviation_max_mm")) f.dev_max = r["surface"]["deviation_max_mm"].get<double>();
  f.ce_max = r.at("contour_error").at("cutting_moves").at("max_abs_mm").get<double>();
  f.ce_rms = r.at("contour_error").at("cutting_moves").at("rms_mm").get<double>();
  f.cycle = r.at("interpolation").at("cycle_time_s").get<double>();
  return f;
}

void expect_row(const Table& t, std::size_t row, const Figures& f, const std::string& what) {
  SCOPED_TRACE(what + ", row " + std::to_string(row + 1));
  EXPECT_EQ(t.at(row, "status"), "ok") << t.at(row, "error");
  EXPECT_EQ(num(t.at(row, "marks")), f.marks);
  // Exactly the run's figures (shortest round-trip decimal of mm x 1000 on both sides).
  auto same = [&](const std::string& col, const std::optional<double>& v, double scale) {
    if (!v) {
      EXPECT_EQ(t.at(row, col), "") << col;
      return;
    }
    EXPECT_EQ(num(t.at(row, col)), *v * scale) << col;
  };
  same("mark_depth_um", f.depth, 1e3);
  same("deviation_min_um", f.dev_min, 1e3);
  same("deviation_max_um", f.dev_max, 1e3);
  same("contour_error_max_um", f.ce_max, 1e3);
  same("contour_error_rms_um", f.ce_rms, 1e3);
  same("cycle_time_s", f.cycle, 1.0);
  EXPECT_GT(num(t.at(row, "cpu_time_s")), 0.0);
}

// Every column but the CPU time.
void expect_same_table(const Table& a, const Table& b, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_EQ(a.names, b.names);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (std::size_t r = 0; r < a.rows.size(); ++r)
    for (std::size_t c = 0; c < a.names.size(); ++c)
      if (a.names[c] != "cpu_time_s") {
        EXPECT_EQ(a.rows[r][c], b.rows[r][c]) << "row " << r + 1 << " " << a.names[c];
      }
}

}  // namespace

TEST(StudyCli, GridOfEightMatchesSeparateRunsOnOneTwoAndThreeRanks) {
  TempDir tmp("vmsim_study_");
  const fs::path root = tmp.path();
  make_layout(root);
  write(root / "studies" / "grid.toml", R"([study]
name = "kv_feed_tolerance"
job = "../part/job.toml"

[grid]
feed_scale = [0.5, 1.0]
machine.axes.X.drive.kv_1000_per_min = [3.0, 6.0]
interpolation.tolerance_mm = [0.005, 0.02]
)");

  // The reference: eight separate vmsim run invocations on files edited as text.
  const std::string machine_text = slurp(root / "machines" / "mikron.toml");
  std::vector<Figures> ref;
  std::vector<std::array<std::string, 3>> values;
  for (const char* fs_ : {"0.5", "1.0"})
    for (const char* kv : {"3.0", "6.0"})
      for (const char* tol : {"0.005", "0.02"}) {
        const std::string tag = std::to_string(ref.size() + 1);
        // X is the first [[axes]] of the Mikron file: its drive's kv line is the first after name = "X".
        write(root / "ref" / tag / "machine.toml", replace_line(machine_text, "name = \"X\"", "kv_1000_per_min", kv));
        std::string job = replace_line(kBaseJob, "[interpolation]", "tolerance_mm", tol);
        job = replace_line(job, "[job]", "machine", "\"../ref/" + tag + "/machine.toml\"");
        write(root / "part" / ("ref_" + tag + ".toml"), job);
        const CliRun r = study_cli(
            "", "run part/ref_" + tag + ".toml --out ref/" + tag + "/out --feed-scale " + fs_ + " --no-render -q", root,
            tmp);
        ASSERT_EQ(r.code, 0) << r.err;
        ref.push_back(figures_of(read_json(root / "ref" / tag / "out" / "report.json")));
        values.push_back({fs_, kv, tol});
      }
  // The overrides act as they should on the reference itself (so the comparison below is not of eight equal rows):
  // half the feed takes longer; the softer X position loop (Kv 3 vs 6) follows the path less closely.
  EXPECT_GT(*ref[0].cycle, *ref[4].cycle);
  EXPECT_GT(*ref[5].ce_max, *ref[7].ce_max);

  std::vector<Table> tables;
  for (int np : {1, 2, 3}) {
    const std::string out = "out" + std::to_string(np);
    const CliRun r =
        study_cli(np == 1 ? std::string() : fmt_mpirun(np), "study studies/grid.toml --out " + out, root, tmp);
    ASSERT_EQ(r.code, 0) << "np " << np << ": " << r.out << r.err;
    EXPECT_NE(r.out.find("8 ok, 0 failed"), std::string::npos) << r.out;
    const Table t = read_table(root / out / "results.csv");
    ASSERT_EQ(t.rows.size(), 8u);
    for (std::size_t k = 0; k < 8; ++k) {
      EXPECT_EQ(t.at(k, "variation"), std::to_string(k + 1));
      EXPECT_EQ(num(t.at(k, "feed_scale")), std::stod(values[k][0]));
      EXPECT_EQ(num(t.at(k, "machine.axes.X.drive.kv_1000_per_min")), std::stod(values[k][1]));
      EXPECT_EQ(num(t.at(k, "interpolation.tolerance_mm")), std::stod(values[k][2]));
      expect_row(t, k, ref[k], "np " + std::to_string(np));
    }
    const nlohmann::json sj = read_json(root / out / "study.json");
    EXPECT_EQ(sj["ranks"], np);
    EXPECT_EQ(sj["summary"]["ok"], 8);
    // Each variation's own files are there, with its run's report and page; the study's page links each.
    EXPECT_TRUE(fs::exists(root / out / "variations" / "008" / "report.json"));
    vmsim_test::expect_report_html(root / out);
    vmsim_test::expect_report_html(root / out / "variations" / "008", "--pictures no");
    tables.push_back(t);
  }
  expect_same_table(tables[0], tables[1], "1 vs 2 ranks");
  expect_same_table(tables[0], tables[2], "1 vs 3 ranks");
}

TEST(StudyCli, FailingVariationsAreReportedAndTheOthersKept) {
  TempDir tmp("vmsim_study_");
  const fs::path root = tmp.path();
  make_layout(root);
  write(root / "studies" / "bad.toml", R"([study]
job = "../part/job.toml"

[common]
removal.spacing_mm = 0.5

[[variation]]
name = "base"

[[variation]]
name = "negative kv"
machine.axes.X.drive.kv_1000_per_min = -2.0

[[variation]]
name = "typo"
interpolation.tolerance_mx = 0.01

[[variation]]
name = "no W axis"
machine.axes.W.drive.kf = 0.5

[[variation]]
name = "slow"
feed_scale = 0.5
)");
  const CliRun r = study_cli(fmt_mpirun(2), "study studies/bad.toml --out out --keep summary", root, tmp);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("2 ok, 3 failed"), std::string::npos) << r.out;
  const Table t = read_table(root / "out" / "results.csv");
  ASSERT_EQ(t.rows.size(), 5u);
  EXPECT_EQ(t.at(0, "status"), "ok");
  EXPECT_EQ(t.at(4, "status"), "ok");
  EXPECT_FALSE(t.at(0, "contour_error_max_um").empty());
  EXPECT_GT(num(t.at(4, "cycle_time_s")), num(t.at(0, "cycle_time_s")));
  // Each failure names the study file, the variation and the key.
  struct Bad {
    std::size_t row;
    std::string name, key;
  };
  for (const Bad& b :
       {Bad{1, "negative kv", "kv_1000_per_min"}, Bad{2, "typo", "tolerance_mx"}, Bad{3, "no W axis", "'W'"}}) {
    EXPECT_EQ(t.at(b.row, "status"), "failed");
    const std::string e = t.at(b.row, "error");
    EXPECT_NE(e.find("bad.toml"), std::string::npos) << e;
    EXPECT_NE(e.find("variation " + std::to_string(b.row + 1) + " (" + b.name + ")"), std::string::npos) << e;
    EXPECT_NE(e.find(b.key), std::string::npos) << e;
    EXPECT_EQ(t.at(b.row, "contour_error_max_um"), "");
  }
  // A key the run rejects (in the variation's generated files) is also traced to the line of the study that sets it.
  EXPECT_NE(t.at(1, "error").find("bad.toml:12:"), std::string::npos) << t.at(1, "error");
  EXPECT_NE(t.at(2, "error").find("bad.toml:16:"), std::string::npos) << t.at(2, "error");
  // --keep summary: the variation's job, report and log, not its surfaces.
  EXPECT_TRUE(fs::exists(root / "out" / "variations" / "001" / "report.json"));
  EXPECT_TRUE(fs::exists(root / "out" / "variations" / "001" / "run.log"));
  EXPECT_FALSE(fs::exists(root / "out" / "variations" / "001" / "surface.x3p"));
  // The pages: the failed rows with their messages, and each kept run's page without links to what was removed.
  vmsim_test::expect_report_html(root / "out", "--note 'negative kv'");
  vmsim_test::expect_report_html(root / "out" / "variations" / "001", "--pictures no");
}

// A variation whose run crashes (a segfault: the test hook VMSIM_TEST_SEGFAULT_JOB=<job name> makes vmsim run raise
// SIGSEGV for that job, README "What you can rely on") becomes its row, naming the signal; the others are kept and
// results.csv is written, on one process and on two ranks. Reference: the same study's rows without the hook.
TEST(StudyCli, AVariationThatCrashesBecomesItsRow) {
  TempDir tmp("vmsim_study_");
  const fs::path root = tmp.path();
  make_layout(root);
  write(root / "studies" / "crash.toml", R"([study]
job = "../part/job.toml"

[common]
removal.spacing_mm = 0.5

[[variation]]
name = "base"

[[variation]]
name = "crashes"
job.name = "crash_me"

[[variation]]
name = "slow"
feed_scale = 0.5
)");
  for (int np : {1, 2}) {
    const std::string out = "out" + std::to_string(np);
    const std::string prefix = "env VMSIM_TEST_SEGFAULT_JOB=crash_me " + (np == 1 ? std::string() : fmt_mpirun(np));
    const CliRun r = study_cli(prefix, "study studies/crash.toml --out " + out, root, tmp);
    ASSERT_EQ(r.code, 0) << np << " ranks\n" << r.out << r.err;
    EXPECT_NE(r.out.find("2 ok, 1 failed"), std::string::npos) << r.out;
    const Table t = read_table(root / out / "results.csv");
    ASSERT_EQ(t.rows.size(), 3u);
    EXPECT_EQ(t.at(0, "status"), "ok");
    EXPECT_EQ(t.at(1, "status"), "failed");
    EXPECT_EQ(t.at(2, "status"), "ok");
    const std::string e = t.at(1, "error");
    EXPECT_NE(e.find("variation 2 (crashes)"), std::string::npos) << e;
    EXPECT_NE(e.find("SIGSEGV"), std::string::npos) << e;
    EXPECT_FALSE(t.at(2, "contour_error_max_um").empty());
    EXPECT_TRUE(fs::exists(root / out / "variations" / "003" / "report.json"));
    EXPECT_TRUE(fs::exists(root / out / "variations" / "002" / "run.log"));
  }
}

TEST(StudyCli, BadStudyFilesNameTheFileAndTheKey) {
  TempDir tmp("vmsim_study_");
  const fs::path root = tmp.path();
  make_layout(root);
  struct Case {
    std::string text, expect;
  };
  const std::vector<Case> cases = {
      {"[study]\njob = \"../part/job.toml\"\n[grids]\nfeed_scale = [1.0]\n", "key 'grids'"},
      {"[study]\njob = \"../part/nope.toml\"\n[grid]\nfeed_scale = [1.0]\n", "key 'study.job'"},
      {"[grid]\nfeed_scale = [1.0]\n", "[study]"},
      {"[study]\njob = \"../part/job.toml\"\n[grid]\nfeed_scale = 0.5\n", "key 'grid.feed_scale'"},
      {"[study]\njob = \"../part/job.toml\"\n[grid]\nfeed_scale = []\n", "key 'grid.feed_scale'"},
      {"[study]\njob = \"../part/job.toml\"\n[grid]\ninterpolaton.tolerance_mm = [0.01]\n",
       "key 'interpolaton.tolerance_mm'"},
      {"[study]\njob = \"../part/job.toml\"\n[grid]\nmachine.axis.X.drive.kf = [0.5]\n",
       "key 'machine.axis.X.drive.kf'"},
      {"[study]\njob = \"../part/job.toml\"\n[[variation]]\nfeed_scale = -1.0\n", "key 'feed_scale'"},
      {"[study]\njob = \"../part/job.toml\"\n[[variation]]\nname = \"a\"\n[[variation]]\nname = \"a\"\n",
       "key 'variation.name'"},
      {"[study]\njob = \"../part/job.toml\"\n[grid]\nfeed_scale = [1.0]\n[[variation]]\nfeed_scale = 1.0\n",
       "key 'grid'"},
      {"[study]\njob = \"../part/job.toml\"\n", "expected a [grid] table or [[variation]] tables"},
      {"[study]\njob = \"../part/job.toml\"\n[grid\n", "bad.toml:3"},
  };
  for (const Case& c : cases) {
    write(root / "studies" / "bad.toml", c.text);
    const CliRun r = study_cli("", "study studies/bad.toml --out out", root, tmp);
    EXPECT_EQ(r.code, 2) << c.text << r.err;
    EXPECT_NE(r.err.find("bad.toml"), std::string::npos) << c.text << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.text << r.err;
    EXPECT_FALSE(fs::exists(root / "out" / "results.csv")) << c.text;
  }
  // Under mpirun the error ends every rank (no rank left waiting for work).
  write(root / "studies" / "bad.toml", cases[3].text);
  const CliRun r = study_cli(fmt_mpirun(2), "study studies/bad.toml --out out", root, tmp);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("key 'grid.feed_scale'"), std::string::npos) << r.err;
}

// The study file's semantics, in-process: the grid's order and names, [common] before a variation's own overrides,
// "*" over every axis, and the base job's relative paths made absolute in the variation's files.
TEST(Study, GridOrderOverridesAndPaths) {
  TempDir tmp("vmsim_study_");
  const fs::path root = tmp.path();
  make_layout(root);
  write(root / "studies" / "s.toml", R"([study]
job = "../part/job.toml"
[common]
machine.axes."*".drive.kf = 0.25
interpolation.tolerance_mm = 0.01
[grid]
interpolation.tolerance_mm = [0.03, 0.04]
feed_scale = [0.5, 1, 2]
)");
  const vmsim::sim::Study s = vmsim::sim::load_study(root / "studies" / "s.toml");
  ASSERT_EQ(s.variations.size(), 6u);
  EXPECT_EQ(s.varied_keys, (std::vector<std::string>{"interpolation.tolerance_mm", "feed_scale"}));
  EXPECT_EQ(s.variations[0].name, "tolerance_mm=0.03 feed_scale=0.5");
  EXPECT_EQ(s.variations[4].name, "tolerance_mm=0.04 feed_scale=1");
  // Keys with the same last part are named by as much of their tail as tells them apart.
  write(root / "studies" / "xz.toml",
        "[study]\njob = \"../part/job.toml\"\n[grid]\n"
        "machine.axes.X.drive.kv_1000_per_min = [3.0]\nmachine.axes.Z.drive.kv_1000_per_min = [4.5]\n");
  EXPECT_EQ(vmsim::sim::load_study(root / "studies" / "xz.toml").variations[0].name,
            "X.drive.kv_1000_per_min=3 Z.drive.kv_1000_per_min=4.5");
  const vmsim::sim::PreparedVariation p = vmsim::sim::prepare_variation(s, s.variations[5]);
  EXPECT_EQ(p.feed_scale, 2.0);
  const toml::table job = toml::parse(p.job_toml);
  EXPECT_EQ(job["interpolation"]["tolerance_mm"].value<double>(), 0.04);  // the variation's own, after [common]
  EXPECT_EQ(job["removal"]["spacing_mm"].value<double>(), 0.25);          // the base's
  for (const char* k : {"program", "tool_table"}) {
    const fs::path path = *job["job"][k].value<std::string>();
    EXPECT_TRUE(path.is_absolute() && fs::exists(path)) << k << " " << path;
  }
  EXPECT_TRUE(fs::exists(*job["stock"]["file"].value<std::string>()));
  EXPECT_EQ(job["job"]["machine"].value<std::string>(), "machine.toml");
  ASSERT_TRUE(p.machine_toml);
  const toml::table m = toml::parse(*p.machine_toml);
  int axes = 0;
  for (const auto& ax : *m["axes"].as_array()) {
    EXPECT_EQ((*ax.as_table())["drive"]["kf"].value<double>(), 0.25);
    ++axes;
  }
  EXPECT_EQ(axes, 5);
}

// A worker rank that stops (the test hook VMSIM_TEST_STOP_RANK=1: rank 1 stops itself with SIGSTOP as it starts)
// never asks for a variation: the watchdog (--watchdog-s 3) ends the study naming the rank and the exchange, instead
// of waiting for it for ever.
TEST(StudyCli, AStoppedWorkerIsNamedByTheWatchdog) {
  TempDir tmp("vmsim_study_");
  const fs::path root = tmp.path();
  make_layout(root);
  write(root / "studies" / "two.toml", R"([study]
job = "../part/job.toml"

[common]
removal.spacing_mm = 0.5

[[variation]]
name = "base"

[[variation]]
name = "slow"
feed_scale = 0.5
)");
  const CliRun r = study_cli("env VMSIM_TEST_STOP_RANK=1 timeout 300 " + fmt_mpirun(2),
                             "study studies/two.toml --out out --watchdog-s 3", root, tmp);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.code, 124) << "timed out: the study hung";
  EXPECT_NE(r.err.find("rank 1 did not reach study: the first request for a variation within 3 s"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(root / "out"));
}
