// Tiled `vmsim run` under MPI (app/tiled_run.hpp): `mpirun -np 2` and `-np 3 --oversubscribe` split the stock into
// bands of dexel rows, one per rank. Reference: the same job run as one plain process by the same binary; the
// gathered outputs (height grids, the part mesh, the marks) must be identical byte for byte, for a z-map job (the
// plane-cylinder part's fast pass, coarse), a five-axis tri-dexel job (one turn of parts/five_axis' spiral) and an
// N-buffer job (parts/corner, needles on the part another job leaves).
// --tiles-out: the tiles' X3P files, stitched by the manifest's rows, give the one-process grid exactly. Errors: a
// rank that fails alone ends every rank with its message and a non-zero exit (no hang: a time limit here), bad
// input names its key. --plan: its rays and field bytes against the field the run actually made (report.json).
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/app/cli_util.hpp"

using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;

namespace {

const std::string kPartsRoot = std::string(VMSIM_SOURCE_DIR) + "/parts";

// Runs vmsim with `args` as one process (ranks 0) or under mpirun; returns the exit code, stderr in `err`. A time
// limit turns a hang into a failure.
int run_vmsim(int ranks, const std::string& args, const fs::path& log, std::string* err = nullptr,
              const std::string& env = "") {
  std::string cmd = env + "timeout 300 ";
  if (ranks > 0)
    cmd +=
        std::string("'") + VMSIM_MPIEXEC + "' -np " + std::to_string(ranks) + " --allow-run-as-root --oversubscribe ";
  cmd += std::string("'") + VMSIM_EXE + "' " + args + " >'" + log.string() + ".out' 2>'" + log.string() + "'";
  const int status = std::system(cmd.c_str());
  if (err) *err = slurp(log);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

nlohmann::json report(const fs::path& dir) { return nlohmann::json::parse(slurp(dir / "report.json")); }

// The plane-cylinder part's fast pass (parts/plane_cylinder) at 0.2 mm instead of 0.05, against the same pass at
// 1/100 of its feeds.
fs::path plane_cylinder_job(const fs::path& dir) {
  const fs::path job = dir / "pc.toml";
  std::ofstream out(job);
  out << "[job]\nname = \"pc_coarse\"\nmachine = \"" << kPartsRoot << "/machines/mikron_ucp710.toml\"\n"
      << "program = \"" << kPartsRoot << "/plane_cylinder/plane_cylinder_fast.ngc\"\ntool_table = \"" << kPartsRoot
      << "/plane_cylinder/tools.tbl\"\nstart_mm = [-8.0, 5.0, 40.0]\n"
      << "[tool]\ntype = \"ball\"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0\n"
      << "[stock]\ntype = \"stl\"\nfile = \"" << kPartsRoot << "/plane_cylinder/plane_cylinder_stock.stl\"\n"
      << "[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n"
      << "[removal]\nfield = \"zmap\"\nspacing_mm = 0.2\nmotion = \"actual\"\n"
      << "[reference]\nkind = \"feed\"\nfeed_scale = 0.01\n";
  return job;
}

// One turn of parts/five_axis' spiral (a ball-end along the normal of a sphere RS 30, A 10 -> 13 deg, C one turn)
// on a box stock, tri-dexel at 0.5 mm, the drives' motion against the programmed one.
fs::path five_axis_job(const fs::path& dir) {
  constexpr double kPi = 3.14159265358979323846, kRs = 30.0;
  {
    std::ofstream cl(dir / "spiral.cl");
    cl << "PARTNO/TILED\nUNITS/MM\nMULTAX/ON\nRAPID\n";
    auto go = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "GOTO/%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n", p.x(), p.y(), p.z(), n.x(), n.y(), n.z());
      cl << buf;
    };
    for (int k = 0; k <= 360; k += 2) {
      const double t = (10.0 + 3.0 * k / 360) * kPi / 180, p = k * kPi / 180;
      const Eigen::Vector3d n(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
      if (k == 0) go(kRs * n + 20 * n, n), cl << "FEDRAT/MMPM,5000.0\n";
      go(kRs * n, n);
      if (k == 360) go(kRs * n + 20 * n, n);
    }
    cl << "FINI\n";
  }
  const fs::path job = dir / "five.toml";
  std::ofstream out(job);
  out << "[job]\nname = \"five_axis_tiled\"\nmachine = \"" << kPartsRoot << "/machines/mikron_ucp710.toml\"\n"
      << "program = \"spiral.cl\"\n"
      << "[tool]\ntype = \"ball\"\ndiameter_mm = 10.0\nflute_length_mm = 6.0\nlength_mm = 6.0\n"
      << "[stock]\ntype = \"box\"\nmin_mm = [-15.0, -15.0, 24.0]\nmax_mm = [15.0, 15.0, 30.05]\n"
      << "[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n"
      << "[removal]\nfield = \"tridexel\"\nspacing_mm = 0.5\nmotion = \"actual\"\ntrack_tolerance_mm = 0.002\n"
      << "[reference]\nkind = \"program\"\n";
  return job;
}

void expect_same_files(const fs::path& a, const fs::path& b, const std::vector<std::string>& files) {
  for (const std::string& f : files) {
    ASSERT_TRUE(fs::exists(a / f)) << (a / f);
    ASSERT_TRUE(fs::exists(b / f)) << (b / f);
    EXPECT_TRUE(slurp(a / f) == slurp(b / f)) << f << " differs between " << a << " and " << b;
  }
}

void expect_tiled_equals_one_process(const fs::path& job, const fs::path& dir, const std::vector<std::string>& files) {
  const std::string common = "run '" + job.string() + "' --quiet --no-render --out ";
  std::string err;
  ASSERT_EQ(run_vmsim(0, common + "'" + (dir / "one").string() + "'", dir / "one.log", &err), 0) << err;
  const nlohmann::json r1 = report(dir / "one");
  EXPECT_FALSE(r1.contains("tiles"));
  for (const int n : {2, 3}) {
    const fs::path out = dir / ("np" + std::to_string(n));
    ASSERT_EQ(run_vmsim(n, common + "'" + out.string() + "'", dir / ("np" + std::to_string(n) + ".log"), &err), 0)
        << err;
    expect_same_files(dir / "one", out, files);
    const nlohmann::json rn = report(out);
    EXPECT_EQ(rn["marks"], r1["marks"]);
    EXPECT_EQ(rn["removal"]["rays"], r1["removal"]["rays"]);
    EXPECT_EQ(rn["surface"], r1["surface"]);
    ASSERT_TRUE(rn.contains("tiles"));
    EXPECT_EQ(rn["tiles"]["ranks"], n);
    double rays = 0;
    for (const auto& t : rn["tiles"]["per_rank"]) {
      rays += t["rays"].get<double>();
      EXPECT_LE(t["sweeps"].get<double>(), r1["removal"]["sweeps"].get<double>());
      EXPECT_GT(t["peak_rss_bytes"].get<double>(), 0);
    }
    EXPECT_EQ(rays, r1["removal"]["rays"].get<double>());
    // The files rank 0 lists are those of the one-process run (the tiles section aside).
    EXPECT_EQ(rn["files"], r1["files"]);
  }
}

}  // namespace

TEST(TiledRunCli, PlaneCylinderZmapTilesGiveTheOneProcessResult) {
  TempDir tmp("vmsim_tiled_");
  expect_tiled_equals_one_process(plane_cylinder_job(tmp.path()), tmp.path(),
                                  {"surface.npy", "surface.csv", "reference.csv", "deviation.npy", "part.stl"});
  // The mark is there to be compared (the fast pass' fillet mark, the feed-drive simulation paper), not an empty
  // result.
  EXPECT_FALSE(report(tmp.path() / "np2")["marks"].empty());
}

TEST(TiledRunCli, FiveAxisTridexelTilesGiveTheOneProcessResult) {
  TempDir tmp("vmsim_tiled_");
  expect_tiled_equals_one_process(
      five_axis_job(tmp.path()), tmp.path(),
      {"surface.npy", "deviation.npy", "part.stl", "part.vtp"});  // part.vdb: OpenVDB writes a random file UUID
}

// N-buffer needles (blocks of 64 per tile) on a stock another job leaves (the tiles run that job too): the corner
// part's fast pass (parts/corner) as it is.
TEST(TiledRunCli, CornerNeedleTilesGiveTheOneProcessResult) {
  TempDir tmp("vmsim_tiled_");
  expect_tiled_equals_one_process(kPartsRoot + "/corner/job_fast.toml", tmp.path(), {"needles.csv"});
}

TEST(TiledRunCli, TilesOutStitchToTheOneProcessGrid) {
  TempDir tmp("vmsim_tiled_");
  const fs::path job = plane_cylinder_job(tmp.path());
  std::string err;
  ASSERT_EQ(run_vmsim(0, "run '" + job.string() + "' -q --no-render --out '" + (tmp.path() / "one").string() + "'",
                      tmp.path() / "one.log", &err),
            0)
      << err;
  ASSERT_EQ(run_vmsim(3, "run '" + job.string() + "' -q --tiles-out --out '" + (tmp.path() / "t").string() + "'",
                      tmp.path() / "t.log", &err),
            0)
      << err;
  const auto whole = vmsim::metrology::read_x3p(tmp.path() / "one" / "surface.x3p").grid;
  const auto wdev = vmsim::metrology::read_x3p(tmp.path() / "one" / "deviation.x3p").grid;
  const nlohmann::json m = nlohmann::json::parse(slurp(tmp.path() / "t" / "tiles.json"));
  ASSERT_EQ(m["tiles"].size(), 3u);
  EXPECT_EQ(m["grid"]["nx"], whole.nx());
  EXPECT_EQ(m["grid"]["ny"], whole.ny());
  EXPECT_EQ(m["grid"]["dx_mm"].get<double>(), whole.dx_mm);
  Eigen::Index rows = 0;
  for (const auto& t : m["tiles"]) {
    const auto s = vmsim::metrology::read_x3p(tmp.path() / "t" / t["surface"].get<std::string>()).grid;
    const auto d = vmsim::metrology::read_x3p(tmp.path() / "t" / t["deviation"].get<std::string>()).grid;
    const Eigen::Index j0 = t["first_row"].get<Eigen::Index>();
    EXPECT_EQ(j0, rows);
    ASSERT_EQ(s.nx(), whole.nx());
    EXPECT_EQ(s.y0_mm, t["y_min_mm"].get<double>());
    EXPECT_NEAR(s.y0_mm, whole.y(j0), 1e-12);
    for (Eigen::Index j = 0; j < s.ny(); ++j)
      for (Eigen::Index i = 0; i < s.nx(); ++i) {
        const double a = whole.z_mm(j0 + j, i), b = s.z_mm(j, i), da = wdev.z_mm(j0 + j, i), db = d.z_mm(j, i);
        ASSERT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << "surface row " << j0 + j << " col " << i;
        ASSERT_TRUE((std::isnan(da) && std::isnan(db)) || da == db) << "deviation row " << j0 + j << " col " << i;
      }
    rows += s.ny();
  }
  EXPECT_EQ(rows, whole.ny());
  EXPECT_EQ(report(tmp.path() / "t")["tiles"]["ranks"], 3);
}

TEST(TiledRunCli, ARankThatFailsEndsEveryRankWithItsMessage) {
  TempDir tmp("vmsim_tiled_");
  const fs::path job = plane_cylinder_job(tmp.path());
  // Rank 1's tile file cannot be written (the test hook VMSIM_TEST_FAIL_TILE=1: the run writes into a fresh staging
  // directory, where nothing can be planted beforehand); ranks 0 and 2 succeed and wait for it.
  std::string err;
  const int code = run_vmsim(3, "run '" + job.string() + "' -q --tiles-out --out '" + (tmp.path() / "t").string() + "'",
                             tmp.path() / "t.log", &err, "env VMSIM_TEST_FAIL_TILE=1 ");
  EXPECT_NE(code, 0);
  EXPECT_NE(code, 124) << "timed out: a rank hung";
  EXPECT_NE(err.find("surface_0001.x3p"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(tmp.path() / "t" / "tiles.json"));
  EXPECT_FALSE(fs::exists(tmp.path() / "t" / "report.json"));

  // Bad input on every rank: the message names the key; the exit code is the input-error code.
  {
    std::string s = slurp(job);
    s.replace(s.find("spacing_mm = 0.2"), 16, "spacing_mm = -0.2");
    std::ofstream(tmp.path() / "bad.toml") << s;
  }
  const int bad = run_vmsim(
      2, "run '" + (tmp.path() / "bad.toml").string() + "' -q --no-render --out '" + (tmp.path() / "b").string() + "'",
      tmp.path() / "b.log", &err);
  EXPECT_NE(bad, 0);
  EXPECT_NE(bad, 124);
  EXPECT_NE(err.find("spacing_mm"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(tmp.path() / "b" / "report.json"));

  // A level set does not tile: a clear error, not a different result.
  {
    std::string s = slurp(job);
    s.replace(s.find("[removal]\n"), 10, "[removal]\nmethod = \"vdb\"\nvoxel_mm = 0.2\n");
    std::ofstream(tmp.path() / "vdb.toml") << s;
  }
  const int vdb = run_vmsim(
      2, "run '" + (tmp.path() / "vdb.toml").string() + "' -q --no-render --out '" + (tmp.path() / "v").string() + "'",
      tmp.path() / "v.log", &err);
  EXPECT_EQ(vdb, 2);
  EXPECT_NE(err.find("vdb"), std::string::npos) << err;
}

// A rank that stops (kill -STOP, a stalled file system: here the test hook VMSIM_TEST_STOP_RANK=1 makes rank 1 stop
// itself with SIGSTOP when it reaches the tiles' gathering) would hang the job: the watchdog (VMSIM_WATCHDOG_S, 3 s
// here) ends it with a message naming the rank and the stage; nothing is written to --out.
TEST(TiledRunCli, AStoppedRankIsNamedByTheWatchdog) {
  TempDir tmp("vmsim_tiled_");
  const fs::path job = plane_cylinder_job(tmp.path());
  std::string err;
  const int code = run_vmsim(2, "run '" + job.string() + "' -q --no-render --out '" + (tmp.path() / "w").string() + "'",
                             tmp.path() / "w.log", &err, "env VMSIM_WATCHDOG_S=3 VMSIM_TEST_STOP_RANK=1 ");
  EXPECT_NE(code, 0);
  EXPECT_NE(code, 124) << "timed out: the job hung";
  EXPECT_NE(err.find("rank 1 did not reach the gathering of the tiles"), std::string::npos) << err;
  EXPECT_NE(err.find("VMSIM_WATCHDOG_S"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(tmp.path() / "w"));
  // A limit that is not a number is refused.
  const int bad = run_vmsim(2, "run '" + job.string() + "' -q --no-render --out '" + (tmp.path() / "x").string() + "'",
                            tmp.path() / "x.log", &err, "env VMSIM_WATCHDOG_S=soon ");
  EXPECT_NE(bad, 0);
  EXPECT_NE(bad, 124);
  EXPECT_NE(err.find("VMSIM_WATCHDOG_S: expected a positive number"), std::string::npos) << err;
}

TEST(TiledRunCli, PlanStatesTheFieldTheRunMakes) {
  TempDir tmp("vmsim_tiled_");
  const fs::path job = plane_cylinder_job(tmp.path());
  std::string err;
  ASSERT_EQ(run_vmsim(0,
                      "run '" + job.string() + "' --plan --ranks 2 --memory-per-rank-gb 0.5 -q --out '" +
                          (tmp.path() / "plan").string() + "'",
                      tmp.path() / "plan.log", &err),
            0)
      << err;
  ASSERT_EQ(run_vmsim(2, "run '" + job.string() + "' -q --no-render --out '" + (tmp.path() / "np2").string() + "'",
                      tmp.path() / "np2.log", &err),
            0)
      << err;
  const nlohmann::json p = nlohmann::json::parse(slurp(tmp.path() / "plan" / "plan.json"));
  const nlohmann::json r = report(tmp.path() / "np2");
  // Rays: exact. Bytes: the field before cuts split rays; a ball end cutting a z-map from above splits none.
  EXPECT_EQ(p["field"]["rays"].get<double>(), r["removal"]["rays"].get<double>());
  EXPECT_EQ(p["field"]["bytes"].get<double>(), r["removal"]["memory_bytes"].get<double>());
  EXPECT_EQ(p["motion"]["sweeps"].get<double>(), r["removal"]["sweeps"].get<double>());
  EXPECT_EQ(p["motion"]["samples"].get<double>(), r["interpolation"]["setpoints"].get<double>());
  ASSERT_EQ(p["gathered"]["per_rank"].size(), 2u);
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(p["gathered"]["per_rank"][k]["rays"].get<double>(), r["tiles"]["per_rank"][k]["rays"].get<double>());
    // The tile's field and its reference (the run's own count: field + reference of the tile).
    EXPECT_EQ(p["gathered"]["per_rank"][k]["rows"][0].get<double>(), r["tiles"]["per_rank"][k]["rows"].get<double>());
  }
  EXPECT_TRUE(p.contains("advice"));
  EXPECT_GE(p["advice"]["ranks_gathered"].get<int>(), 1);
}

// --watchdog-s sets the same limit and wins over VMSIM_WATCHDOG_S (an hour here, which would hang the test): the
// stopped rank is named within seconds, the message names the option.
TEST(TiledRunCli, WatchdogOptionWinsOverTheVariable) {
  TempDir tmp("vmsim_tiled_");
  const fs::path job = plane_cylinder_job(tmp.path());
  std::string err;
  const int code = run_vmsim(
      2, "run '" + job.string() + "' -q --no-render --watchdog-s 3 --out '" + (tmp.path() / "w").string() + "'",
      tmp.path() / "w.log", &err, "env VMSIM_WATCHDOG_S=3600 VMSIM_TEST_STOP_RANK=1 ");
  EXPECT_NE(code, 0);
  EXPECT_NE(code, 124) << "timed out: the option did not win over the variable";
  EXPECT_NE(err.find("rank 1 did not reach the gathering of the tiles"), std::string::npos) << err;
  EXPECT_NE(err.find("within 3 s"), std::string::npos) << err;
  EXPECT_NE(err.find("--watchdog-s"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(tmp.path() / "w"));
}
