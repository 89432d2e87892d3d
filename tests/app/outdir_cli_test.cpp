// Output directories as a user meets them (issue 18): a rerun into an existing --out leaves nothing of the earlier
// run; a second run into a directory being written is refused; a run killed at any moment (SIGTERM, SIGKILL) leaves
// the previous complete result or the new one, never a mixture, and the next run cleans what it left; the report is
// written when the pictures fail in any way; a path that is not UTF-8 is refused before the run. References: the
// files of a complete run of the same job into a directory of its own (names and sizes), the report's own file
// list, and `vmsim render`'s list of the pictures it drew.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "core/output_dir.hpp"
#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

using vmsim_test::CliRun;
using vmsim_test::quoted_arg;
using vmsim_test::read_json;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;

namespace fs = std::filesystem;

extern char** environ;

namespace {

using vmsim::test::kPartsPath;

// The plane-cylinder fast pass (parts/plane_cylinder), with its paths made absolute so the job can live in TMP:
// job A as the part has it (a reference at 1/100 of the feed, so deviation grids and marks), job B at another
// spacing with no reference (other grid sizes, no deviation files).
fs::path write_job(const TempDir& tmp, const std::string& name, bool reference, double spacing_mm,
                   const fs::path& dir = {}) {
  const fs::path pc = kPartsPath / "plane_cylinder";
  std::string text = slurp(pc / "job_fast.toml");
  auto replace = [&](const std::string& from, const std::string& to) {
    const auto k = text.find(from);
    if (k == std::string::npos) throw std::runtime_error("job_fast.toml: no " + from);
    text.replace(k, from.size(), to);
  };
  replace("\"../machines/mikron_ucp710.toml\"",
          "\"" + (kPartsPath / "machines" / "mikron_ucp710.toml").string() + "\"");
  replace("\"plane_cylinder_fast.ngc\"", "\"" + (pc / "plane_cylinder_fast.ngc").string() + "\"");
  replace("\"tools.tbl\"", "\"" + (pc / "tools.tbl").string() + "\"");
  replace("\"plane_cylinder_stock.stl\"", "\"" + (pc / "plane_cylinder_stock.stl").string() + "\"");
  replace("spacing_mm = 0.05", "spacing_mm = " + std::to_string(spacing_mm));
  replace("name = \"plane_cylinder_fast\"", "name = \"" + name + "\"");
  if (!reference) {
    replace("kind = \"feed\"", "kind = \"none\"");
    replace("feed_scale = 0.01", "");
  }
  const fs::path where = dir.empty() ? tmp.path() : dir;
  fs::create_directories(where);
  const fs::path file = where / (name + ".toml");
  write_file(file, text);
  return file;
}

// Every regular file under DIR (relative names) with its size.
std::map<std::string, std::uintmax_t> files_of(const fs::path& dir) {
  std::map<std::string, std::uintmax_t> m;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) m[fs::relative(e.path(), dir).string()] = e.file_size();
  return m;
}

// Names beside OUT (in its parent) that a run of vmsim left: staging directories and temporary files.
std::vector<std::string> leftovers(const fs::path& out) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(out.parent_path())) {
    const std::string n = e.path().filename().string();
    if (n.find(".vmsim-staging-") != std::string::npos || n.find(".tmp") != std::string::npos) v.push_back(n);
  }
  if (fs::exists(out))
    for (const auto& e : fs::recursive_directory_iterator(out))
      if (e.path().filename().string().find(".tmp") != std::string::npos) v.push_back(e.path().string());
  return v;
}

// vmsim started without a shell (so its pid is vmsim's), stdout and stderr to files in TMP.
pid_t spawn_vmsim(const std::vector<std::string>& args, const TempDir& tmp, const std::string& tag) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, (tmp.path() / (tag + ".out")).c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, (tmp.path() / (tag + ".err")).c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<std::string> all = {VMSIM_EXE};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, VMSIM_EXE, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

// The result in OUT is whole: its report.json parses, every file it lists is there, and the directory holds
// nothing else but the report itself, its page and the marker.
void expect_whole(const fs::path& out, const std::string& when) {
  ASSERT_TRUE(fs::exists(out / "report.json")) << when;
  const nlohmann::json rep = read_json(out / "report.json");
  std::set<std::string> listed;
  for (const auto& f : rep.at("files")) listed.insert(f.get<std::string>());
  for (const std::string& f : listed)
    EXPECT_TRUE(fs::is_regular_file(out / f)) << when << ": " << f << " is listed, absent";
  for (const auto& [name, size] : files_of(out))
    EXPECT_TRUE(listed.count(name) || name == "report.json" || name == "report.html" || name == ".vmsim-output")
        << when << ": " << name << " is not listed in report.json (stale or mixed)";
}

// OUT holds exactly SNAPSHOT's files with their sizes (report.json and report.html hold timings, an X3P's zipped XML
// a date: their names only; the grids' .npy and .csv sizes tell the two jobs apart).
bool same_files(const std::map<std::string, std::uintmax_t>& now,
                const std::map<std::string, std::uintmax_t>& snapshot) {
  if (now.size() != snapshot.size()) return false;
  for (const auto& [name, size] : snapshot) {
    const auto it = now.find(name);
    if (it == now.end()) return false;
    const bool sized = name != "report.json" && name != "report.html" && !name.ends_with(".x3p");
    if (sized && it->second != size) return false;
  }
  return true;
}

}  // namespace

// A rerun of another job into the same --out: nothing of the first run stays, and `vmsim render` draws the second
// run (no deviation map: it has no reference), not the first one's mark under the second one's title.
TEST(OutDirCli, RerunLeavesNoStaleFileAndRenderDrawsTheNewRun) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path a = write_job(tmp, "with_reference", true, 0.1), b = write_job(tmp, "no_reference", false, 0.2);
  CliRun r = run_vmsim("run " + quoted_arg(a) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  ASSERT_TRUE(fs::exists(out / "deviation.csv"));
  r = run_vmsim("run " + quoted_arg(b) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  expect_whole(out, "after the rerun");
  for (const char* stale : {"deviation.csv", "deviation.npy", "deviation.x3p", "reference.csv", "reference.x3p"})
    EXPECT_FALSE(fs::exists(out / stale)) << stale << " of the first run is still there";
  EXPECT_EQ(read_json(out / "report.json").at("job").get<std::string>(), "no_reference");
  EXPECT_TRUE(leftovers(out).empty());

  const CliRun d = run_vmsim("render " + quoted_arg(out) + " --size 480x320", tmp, "env -u DISPLAY ");
  ASSERT_EQ(d.code, 0) << d.err;
  EXPECT_NE(d.out.find("part.png"), std::string::npos) << d.out;
  EXPECT_EQ(d.out.find("deviation"), std::string::npos) << "render drew a deviation map of the earlier run:\n" << d.out;
}

// `vmsim render` reads only what report.json lists: no report (a run that never finished), or a listed file
// missing, is refused naming what is missing.
TEST(OutDirCli, RenderAndCompareRefuseIncompleteOrUnlistedResults) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path b = write_job(tmp, "no_reference", false, 0.2);
  CliRun r = run_vmsim("run " + quoted_arg(b) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  // A stale file beside the listed ones is not read by compare.
  fs::copy_file(out / "surface.x3p", out / "old_surface.x3p");
  CliRun c = run_vmsim("compare -m " + quoted_arg(out / "surface.x3p") + " -p " + quoted_arg(out / "old_surface.x3p") +
                           " --no-render --out " + quoted_arg(tmp.path() / "cmp"),
                       tmp);
  EXPECT_EQ(c.code, 2);
  EXPECT_NE(c.err.find("old_surface.x3p: not listed in"), std::string::npos) << c.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "cmp"));
  // A listed file missing.
  fs::remove(out / "surface.csv");
  CliRun d = run_vmsim("render " + quoted_arg(out), tmp, "env -u DISPLAY ");
  EXPECT_EQ(d.code, 2);
  EXPECT_NE(d.err.find("lists surface.csv, which is missing"), std::string::npos) << d.err;
  // No report.json.
  fs::remove(out / "report.json");
  d = run_vmsim("render " + quoted_arg(out), tmp, "env -u DISPLAY ");
  EXPECT_EQ(d.code, 2);
  EXPECT_NE(d.err.find("no report.json"), std::string::npos) << d.err;
}

// Two runs into one directory at once: the second is refused at once, naming the directory and the first process;
// the first finishes and its result is whole.
TEST(OutDirCli, ASecondRunIntoTheSameDirectoryIsRefused) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path a = write_job(tmp, "with_reference", true, 0.1), b = write_job(tmp, "no_reference", false, 0.2);
  const pid_t first = spawn_vmsim({"run", a.string(), "--quiet", "--no-render", "--out", out.string()}, tmp, "first");
  ASSERT_GT(first, 0);
  // The first run holds the directory once its staging directory exists.
  bool staging = false;
  for (int k = 0; k < 2000 && !staging; ++k) {
    for (const auto& e : fs::directory_iterator(tmp.path()))
      if (e.path().filename().string().rfind(".out.vmsim-staging-", 0) == 0) staging = true;
    if (!staging) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(staging) << "the first run never started writing";
  const CliRun second = run_vmsim("run " + quoted_arg(b) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  int status = 0;
  ASSERT_EQ(waitpid(first, &status, 0), first);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(tmp.path() / "first.err");
  EXPECT_EQ(second.code, 2) << second.out;
  EXPECT_NE(second.err.find(out.string()), std::string::npos) << second.err;
  EXPECT_NE(second.err.find("another process is writing"), std::string::npos) << second.err;
  EXPECT_NE(second.err.find("pid " + std::to_string(first)), std::string::npos) << second.err;
  expect_whole(out, "after the first run");
  EXPECT_EQ(read_json(out / "report.json").at("job").get<std::string>(), "with_reference");
}

// `vmsim run` killed at random moments, 20 times (SIGTERM and SIGKILL in turn), into a directory holding the
// previous complete result of another job (other grid sizes, other files): after each kill the directory holds the
// previous result or the new one, file for file and size for size as a complete run of that job leaves them; after
// SIGTERM no staging directory is left; after SIGKILL the next run removes it.
TEST(OutDirCli, KilledRunsLeaveThePreviousResultOrTheNewOne) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path jobs[2] = {write_job(tmp, "with_reference", true, 0.1), write_job(tmp, "no_reference", false, 0.2)};
  // The references: each job run whole into a directory of its own; and how long a run takes.
  std::map<std::string, std::uintmax_t> snapshot[2];
  double seconds[2];
  for (int j = 0; j < 2; ++j) {
    const fs::path ref = tmp.path() / ("ref" + std::to_string(j));
    const auto t0 = std::chrono::steady_clock::now();
    const CliRun r = run_vmsim("run " + quoted_arg(jobs[j]) + " --quiet --no-render --out " + quoted_arg(ref), tmp);
    seconds[j] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_EQ(r.code, 0) << r.err;
    snapshot[j] = files_of(ref);
  }
  ASSERT_NE(snapshot[0].size(), snapshot[1].size());
  CliRun r = run_vmsim("run " + quoted_arg(jobs[0]) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  int holds = 0;  // which job's result OUT holds
  std::mt19937 rng(20261126);
  int completed = 0, interrupted = 0;
  for (int k = 0; k < 20; ++k) {
    const int next = 1 - holds;
    const int sig = k % 2 == 0 ? SIGTERM : SIGKILL;
    const pid_t pid =
        spawn_vmsim({"run", jobs[next].string(), "--quiet", "--no-render", "--out", out.string()}, tmp, "killed");
    ASSERT_GT(pid, 0);
    // Anywhere from the start to a little past the end of a run.
    const double delay_s = std::uniform_real_distribution<double>(0.0, 1.1 * seconds[next])(rng);
    std::this_thread::sleep_for(std::chrono::duration<double>(delay_s));
    kill(pid, sig);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    const bool finished = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    finished ? ++completed : ++interrupted;
    const std::string when = "kill " + std::to_string(k) + " (" + (sig == SIGTERM ? "SIGTERM" : "SIGKILL") + " after " +
                             std::to_string(delay_s) + " s, exit status " + std::to_string(status) + ")";
    if (sig == SIGTERM && !finished && WIFEXITED(status)) {
      EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM) << when << "\n" << slurp(tmp.path() / "killed.err");
    }
    expect_whole(out, when);
    const auto now = files_of(out);
    const bool is_prev = same_files(now, snapshot[holds]), is_new = same_files(now, snapshot[next]);
    EXPECT_TRUE(is_prev || is_new) << when << ": neither the previous result nor the new one";
    if (is_new) holds = next;
    if (sig == SIGTERM) {  // its own staging directory is gone (an earlier SIGKILL's may wait for the next run)
      for (const std::string& n : leftovers(out))
        EXPECT_EQ(n.find("staging-" + std::to_string(pid) + "-"), std::string::npos) << when << ": " << n;
    }
  }
  // The next run removes what the killed ones left.
  r = run_vmsim("run " + quoted_arg(jobs[1 - holds]) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(same_files(files_of(out), snapshot[1 - holds]));
  const auto left = leftovers(out);
  EXPECT_TRUE(left.empty()) << (left.empty() ? "" : left.front());
  std::printf("%d of 20 runs cut short, %d finished before their signal\n", interrupted, completed);
  // The test means something only if some runs were cut short.
  EXPECT_GE(interrupted, 5) << completed << " runs finished before their kill";
}

// The pictures fail with bad_alloc (a test hook: VMSIM_TEST_PICTURES_THROW=bad_alloc, README "What you can rely
// on"): report.json and every result are written, the report says why there are no pictures, the exit is non-zero.
TEST(OutDirCli, PicturesThrowingBadAllocStillLeaveTheReport) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path b = write_job(tmp, "no_reference", false, 0.2);
  const CliRun r = run_vmsim("run " + quoted_arg(b) + " --quiet --image-size 480x320 --out " + quoted_arg(out), tmp,
                             "env -u DISPLAY VMSIM_TEST_PICTURES_THROW=bad_alloc ");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.err.find("out of memory while drawing"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
  expect_whole(out, "after the pictures failed");
  const nlohmann::json rep = read_json(out / "report.json");
  EXPECT_NE(rep.value("render_error", "").find("out of memory"), std::string::npos);
  EXPECT_TRUE(fs::exists(out / "surface.x3p"));
}

// A job whose directory's name is not UTF-8 (Latin-1 'é'): refused before the run with a message naming it, instead
// of an internal error after the whole run; nothing is written.
TEST(OutDirCli, APathThatIsNotUtf8IsRefusedBeforeTheRun) {
  TempDir tmp;
  const fs::path dir = tmp.path() / "caf\xe9";
  const fs::path job = write_job(tmp, "no_reference", false, 0.1, dir);
  const fs::path out = tmp.path() / "out";
  const CliRun r = run_vmsim("run " + quoted_arg(job) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.err.find("not valid UTF-8"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("caf\\xe9"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  // The output directory likewise.
  const fs::path job_ok = write_job(tmp, "plain", false, 0.2);
  const CliRun o =
      run_vmsim("run " + quoted_arg(job_ok) + " --quiet --no-render --out " + quoted_arg(tmp.path() / "out\xff"), tmp);
  EXPECT_EQ(o.code, 2) << o.out;
  EXPECT_NE(o.err.find("not valid UTF-8"), std::string::npos) << o.err;
  // An input of vmsim compare likewise (it goes into report.json's inputs).
  const CliRun ok =
      run_vmsim("run " + quoted_arg(job_ok) + " --quiet --no-render --out " + quoted_arg(tmp.path() / "ok"), tmp);
  ASSERT_EQ(ok.code, 0) << ok.err;
  fs::copy_file(tmp.path() / "ok" / "surface.x3p", tmp.path() / "scan\xe9.x3p");
  const CliRun c = run_vmsim("compare -m " + quoted_arg(tmp.path() / "scan\xe9.x3p") + " -p " +
                                 quoted_arg(tmp.path() / "ok" / "surface.x3p") + " --no-render --out " +
                                 quoted_arg(tmp.path() / "cmp"),
                             tmp);
  EXPECT_EQ(c.code, 2) << c.out;
  EXPECT_NE(c.err.find("--measured is not valid UTF-8"), std::string::npos) << c.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "cmp"));
}

// Without --out, a command writes NAME_COMMAND/ in the current directory (the job's name for run and interp, the
// scan's stem for compare), never the current directory itself; a second command or job gets its own directory.
TEST(OutDirCli, WithoutOutACommandWritesNameCommandHere) {
  TempDir tmp;
  const fs::path job = write_job(tmp, "plain", false, 0.2);
  CliRun r = run_vmsim("run " + quoted_arg(job) + " --quiet --no-render", tmp, "cd " + quoted_arg(tmp.path()) + " && ");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(tmp.path() / "plain_run" / "report.json"));
  EXPECT_NE(r.out.find("plain_run"), std::string::npos) << r.out;
  r = run_vmsim("interp " + quoted_arg(job) + " --summary-only", tmp, "cd " + quoted_arg(tmp.path()) + " && ");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "plain_interp"));  // --summary-only writes nothing
  fs::copy_file(tmp.path() / "plain_run" / "surface.x3p", tmp.path() / "scan.x3p");
  r = run_vmsim("compare -m scan.x3p -p " + quoted_arg(tmp.path() / "plain_run" / "surface.x3p") + " --no-render", tmp,
                "cd " + quoted_arg(tmp.path()) + " && ");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(tmp.path() / "scan_compare" / "report.json"));
  EXPECT_TRUE(fs::exists(tmp.path() / "plain_run" / "report.json"));  // the run's result is untouched
}

// `vmsim render DIR` holds DIR's lock (core::OutputLock) while it reads DIR and writes DIR/images: while another
// process holds it (here this test, as a run writing DIR would), render is refused naming the holder and writes
// nothing; once it is released, render draws. Reference: the lock's holder as this process wrote it.
TEST(OutDirCli, RenderIsRefusedWhileAnotherProcessHoldsTheDirectory) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path b = write_job(tmp, "no_reference", false, 0.2);
  CliRun r = run_vmsim("run " + quoted_arg(b) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  {
    const vmsim::core::OutputLock held(out, "a test holding the lock");
    const CliRun d = run_vmsim("render " + quoted_arg(out) + " --size 480x320", tmp, "env -u DISPLAY ");
    EXPECT_EQ(d.code, 2) << d.out;
    EXPECT_NE(d.err.find(out.string()), std::string::npos) << d.err;
    EXPECT_NE(d.err.find("another process is writing"), std::string::npos) << d.err;
    EXPECT_NE(d.err.find("a test holding the lock (pid " + std::to_string(::getpid())), std::string::npos) << d.err;
    EXPECT_FALSE(fs::exists(out / "images"));
    // And a run into it is refused the same way.
    r = run_vmsim("run " + quoted_arg(b) + " --quiet --no-render --out " + quoted_arg(out), tmp);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("a test holding the lock"), std::string::npos) << r.err;
  }
  const CliRun d = run_vmsim("render " + quoted_arg(out) + " --size 480x320", tmp, "env -u DISPLAY ");
  EXPECT_EQ(d.code, 0) << d.err;
  EXPECT_TRUE(fs::exists(out / "images" / "part.png")) << d.out;
}

// The memory guards of the X3P reader and of the pictures, reached through the test hook VMSIM_TEST_AVAILABLE_BYTES
// (core::available_memory returns it instead of the machine's figure): a scan or a picture that needs more than is
// available is refused before it is allocated, naming the file or the option, the bytes needed and the bytes
// available. References: the reader's own 57 B per point and the pictures' 17 B per pixel (metrology/x3p.cpp,
// render/window.cpp), against the X3P's point count read here from the run's report.
TEST(OutDirCli, LargeScansAndPicturesAreRefusedAgainstTheAvailableMemory) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path b = write_job(tmp, "no_reference", false, 0.2);
  CliRun r = run_vmsim("run " + quoted_arg(b) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;

  // The run's surface X3P read by compare with 100 kB available.
  const std::string scan = (out / "surface.x3p").string();
  r = run_vmsim("compare -m " + quoted_arg(scan) + " -p " + quoted_arg(scan) + " --no-render --out " +
                    quoted_arg(tmp.path() / "cmp"),
                tmp, "env VMSIM_TEST_AVAILABLE_BYTES=100000 ");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.err.find(scan), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("points need about"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("while 100 kB is available (VMSIM_TEST_AVAILABLE_BYTES"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "cmp"));
  // With the machine's own figure it is read.
  r = run_vmsim("compare -m " + quoted_arg(scan) + " -p " + quoted_arg(scan) + " --no-render --out " +
                    quoted_arg(tmp.path() / "cmp"),
                tmp);
  EXPECT_EQ(r.code, 0) << r.err;

  // A 4000 x 4000 picture needs 17 B x 16e6 = 272 MB; 200 MB available.
  const CliRun d = run_vmsim("render " + quoted_arg(out) + " --size 4000x4000", tmp,
                             "env -u DISPLAY VMSIM_TEST_AVAILABLE_BYTES=200000000 ");
  EXPECT_EQ(d.code, 2) << d.out;
  EXPECT_NE(d.err.find("4000x4000 picture needs about 272 MB while 200 MB is available"), std::string::npos) << d.err;
  EXPECT_NE(d.err.find("--size"), std::string::npos) << d.err;
  EXPECT_EQ(d.err.find("internal error"), std::string::npos) << d.err;
  // And the hook refuses what is not a number of bytes.
  const CliRun bad = run_vmsim("render " + quoted_arg(out) + " --size 480x320", tmp,
                               "env -u DISPLAY VMSIM_TEST_AVAILABLE_BYTES=lots ");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("VMSIM_TEST_AVAILABLE_BYTES: expected a number of bytes"), std::string::npos) << bad.err;
}

namespace {

// The processes whose parent is PID.
std::vector<pid_t> children_of(pid_t pid) {
  std::vector<pid_t> v;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string n = e.path().filename().string();
    if (n.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream st(e.path() / "stat");
    std::string line;
    if (!std::getline(st, line)) continue;
    const auto close = line.rfind(')');  // "pid (comm) state ppid ..."; comm may hold spaces
    if (close == std::string::npos) continue;
    std::istringstream rest(line.substr(close + 2));
    char state = 0;
    long ppid = 0;
    rest >> state >> ppid;
    if (ppid == pid) v.push_back(static_cast<pid_t>(std::stol(n)));
  }
  return v;
}

// The MPI rank of a process launched by mpirun (Open MPI's OMPI_COMM_WORLD_RANK in its environment), or -1.
int rank_of(pid_t pid) {
  const std::string env = slurp(fs::path("/proc") / std::to_string(pid) / "environ");
  const std::string key = std::string("OMPI_COMM_WORLD_RANK=");
  std::size_t k = 0;
  while (k < env.size()) {
    const std::size_t end = env.find('\0', k);
    const std::string var = env.substr(k, end == std::string::npos ? std::string::npos : end - k);
    if (var.rfind(key, 0) == 0) return std::atoi(var.c_str() + key.size());
    if (end == std::string::npos) break;
    k = end + 1;
  }
  return -1;
}

// mpirun -np 2 vmsim ARGS started without a shell; its pid.
pid_t spawn_mpirun(const std::vector<std::string>& args, const TempDir& tmp, const std::string& tag) {
  std::vector<std::string> all = {VMSIM_MPIEXEC,         VMSIM_MPIEXEC_NUMPROC_FLAG, "2",
                                  "--allow-run-as-root", "--oversubscribe",          VMSIM_EXE};
  all.insert(all.end(), args.begin(), args.end());
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, (tmp.path() / (tag + ".out")).c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, (tmp.path() / (tag + ".err")).c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, VMSIM_MPIEXEC, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

// Waits for PID at most LIMIT_S seconds; false (and PID killed) when it had not ended by then.
bool wait_bounded(pid_t pid, double limit_s, int* status) {
  const auto t0 = std::chrono::steady_clock::now();
  while (true) {
    const pid_t w = waitpid(pid, status, WNOHANG);
    if (w == pid) return true;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit_s) {
      kill(pid, SIGKILL);
      waitpid(pid, status, 0);
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

}  // namespace

// Rank 0 of a 2-rank tiled `vmsim run` (rank 0 owns --out: the lock, the staging directory, the swap) killed at random
// moments, 20 times (SIGTERM and SIGKILL in turn), into a directory holding the previous complete result of another
// job: after each kill the directory holds the previous result or the new one (file names and sizes as complete
// 2-rank runs of each job leave them), mpirun and every rank end within 60 s (the watchdog, --watchdog-s 10, bounds a
// rank left waiting), and the next run leaves nothing staged. Long (about a minute and a half here): run by `make
// validate` (scripts/validate.sh), not by `make test`.
TEST(OutDirCli, DISABLED_KilledRank0UnderMpirunLeavesThePreviousResultOrTheNewOne) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path jobs[2] = {write_job(tmp, "with_reference", true, 0.1), write_job(tmp, "no_reference", false, 0.2)};
  auto args = [&](int j, const fs::path& dir) {
    return std::vector<std::string>{"run", jobs[j].string(), "--quiet",   "--no-render", "--watchdog-s",
                                    "10",  "--out",          dir.string()};
  };
  std::map<std::string, std::uintmax_t> snapshot[2];
  double seconds[2];
  for (int j = 0; j < 2; ++j) {
    const fs::path ref = tmp.path() / ("ref" + std::to_string(j));
    const auto t0 = std::chrono::steady_clock::now();
    const pid_t pid = spawn_mpirun(args(j, ref), tmp, "ref");
    ASSERT_GT(pid, 0);
    int status = 0;
    ASSERT_TRUE(wait_bounded(pid, 300, &status));
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(tmp.path() / "ref.err");
    seconds[j] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    snapshot[j] = files_of(ref);
  }
  ASSERT_NE(snapshot[0].size(), snapshot[1].size());
  {
    int status = 0;
    const pid_t pid = spawn_mpirun(args(0, out), tmp, "first");
    ASSERT_TRUE(wait_bounded(pid, 300, &status));
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(tmp.path() / "first.err");
  }
  int holds = 0;
  std::mt19937 rng(20261126);
  int completed = 0, interrupted = 0;
  double longest_end_s = 0;
  const auto t_all = std::chrono::steady_clock::now();
  for (int k = 0; k < 20; ++k) {
    const int next = 1 - holds;
    const int sig = k % 2 == 0 ? SIGTERM : SIGKILL;
    const auto t0 = std::chrono::steady_clock::now();
    const pid_t mpirun = spawn_mpirun(args(next, out), tmp, "killed");
    ASSERT_GT(mpirun, 0);
    // Rank 0 among mpirun's children (Open MPI starts local ranks itself), once it is there.
    pid_t rank0 = -1;
    std::vector<pid_t> ranks;
    while (rank0 < 0 && std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 30) {
      ranks = children_of(mpirun);
      for (pid_t c : ranks)
        if (rank_of(c) == 0) rank0 = c;
      if (rank0 < 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_GT(rank0, 0) << "no rank 0 under mpirun";
    // Anywhere from rank 0's start to a little past the end of a run.
    const double delay_s = std::uniform_real_distribution<double>(0.0, 1.1 * seconds[next])(rng);
    std::this_thread::sleep_for(std::chrono::duration<double>(delay_s));
    const auto t_kill = std::chrono::steady_clock::now();
    kill(rank0, sig);
    int status = 0;
    const bool ended = wait_bounded(mpirun, 60, &status);
    const double end_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_kill).count();
    longest_end_s = std::max(longest_end_s, end_s);
    const std::string when = "kill " + std::to_string(k) + " (" + (sig == SIGTERM ? "SIGTERM" : "SIGKILL") +
                             " to rank 0 after " + std::to_string(delay_s) + " s, mpirun's exit status " +
                             std::to_string(status) + ")";
    ASSERT_TRUE(ended) << when << ": mpirun did not end within 60 s (a rank hangs)";
    // Every rank ends within 10 s of mpirun: once mpirun is gone its ranks are no one's children, so a rank still
    // exiting at that moment, or ended and not yet reaped (a zombie: this container's init may never reap it), is
    // not a hanging rank; one still running after 10 s is.
    for (pid_t c : ranks) {
      auto running = [c] {
        std::ifstream stat("/proc/" + std::to_string(c) + "/stat");
        std::string line;
        if (!std::getline(stat, line)) return false;
        const std::size_t close = line.rfind(')');
        return close != std::string::npos && close + 2 < line.size() && line[close + 2] != 'Z';
      };
      const auto t_end = std::chrono::steady_clock::now();
      while (running() && std::chrono::steady_clock::now() - t_end < std::chrono::seconds(10))
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      EXPECT_FALSE(running()) << when << ": rank process " << c << " still runs 10 s after mpirun ended";
    }
    const bool finished = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    finished ? ++completed : ++interrupted;
    expect_whole(out, when);
    const auto now = files_of(out);
    const bool is_prev = same_files(now, snapshot[holds]), is_new = same_files(now, snapshot[next]);
    EXPECT_TRUE(is_prev || is_new) << when << ": neither the previous result nor the new one\n"
                                   << slurp(tmp.path() / "killed.err");
    if (is_new) holds = next;
    if (sig == SIGTERM) {  // rank 0's own staging directory is gone
      for (const std::string& n : leftovers(out))
        EXPECT_EQ(n.find("staging-" + std::to_string(rank0) + "-"), std::string::npos) << when << ": " << n;
    }
  }
  // The next run removes what the killed ones left.
  int status = 0;
  const pid_t pid = spawn_mpirun(args(1 - holds, out), tmp, "last");
  ASSERT_TRUE(wait_bounded(pid, 300, &status));
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(tmp.path() / "last.err");
  EXPECT_TRUE(same_files(files_of(out), snapshot[1 - holds]));
  const auto left = leftovers(out);
  EXPECT_TRUE(left.empty()) << (left.empty() ? "" : left.front());
  std::printf(
      "%d of 20 runs cut short, %d finished before their signal; complete 2-rank runs %.1f s and %.1f s; "
      "mpirun ended at most %.2f s after a kill; %.0f s for the 20 kills\n",
      interrupted, completed, seconds[0], seconds[1], longest_end_s,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_all).count());
  EXPECT_GE(interrupted, 5) << completed << " runs finished before their kill";
}

// `vmsim run --plan --out DIR` makes DIR a result of its own, as every command does: an earlier run's files are
// replaced whole (DIR then holds plan.json and the marker only), a directory vmsim did not write is refused before
// the motion is computed, and so is a directory another process holds. References: the plan printed on stdout
// (plan.json holds the same sample count) and the lock's holder as this process wrote it.
TEST(OutDirCli, ThePlanWithOutIsAResultDirectoryOfItsOwn) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const fs::path a = write_job(tmp, "with_reference", true, 0.2);
  CliRun r = run_vmsim("run " + quoted_arg(a) + " --quiet --no-render --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  r = run_vmsim("run " + quoted_arg(a) + " --plan --quiet --out " + quoted_arg(out), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::map<std::string, std::uintmax_t> files = files_of(out);
  std::set<std::string> names;
  for (const auto& [name, size] : files) names.insert(name);
  EXPECT_EQ(names, (std::set<std::string>{"plan.json", ".vmsim-output"}));
  EXPECT_TRUE(leftovers(out).empty());
  const nlohmann::json plan = read_json(out / "plan.json");
  const std::string samples =
      std::to_string(static_cast<long long>(plan.at("motion").at("samples").get<double>())) + " setpoints";
  EXPECT_NE(r.out.find(samples), std::string::npos) << samples << " not in:\n" << r.out;

  // Not vmsim's: refused, the user's file kept, nothing planned.
  const fs::path mine = tmp.path() / "mine";
  fs::create_directory(mine);
  write_file(mine / "notes.txt", "mine\n");
  r = run_vmsim("run " + quoted_arg(a) + " --plan --out " + quoted_arg(mine), tmp);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.err.find(mine.string()), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("one process:"), std::string::npos) << r.out;
  EXPECT_EQ(slurp(mine / "notes.txt"), "mine\n");

  // Held by another process: refused naming it, the plan left as it was.
  {
    const vmsim::core::OutputLock held(out, "a test holding the lock");
    r = run_vmsim("run " + quoted_arg(a) + " --plan --quiet --out " + quoted_arg(out), tmp);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.err.find("a test holding the lock (pid " + std::to_string(::getpid())), std::string::npos) << r.err;
  }
  EXPECT_EQ(files_of(out), files);
}
