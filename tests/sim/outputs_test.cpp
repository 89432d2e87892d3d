// [outputs] (core/job.hpp, parts/README.md) honoured by sim::write_run_outputs: which files a small run writes under
// each setting, against the list the keys' documentation gives, the zlib level passed to the VTP writer, and what
// report.json's "outputs" says. The simplified mesh's accuracy is tests/sim/part_mesh_test.cpp's.
#include "tests/app/cli_util.hpp"
#include "core/job.hpp"
#include "core/stl.hpp"
#include "sim/run.hpp"
#include "sim/run_outputs.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

namespace fs = std::filesystem;
using namespace vmsim;
using vmsim_test::TempDir;  // tests/app/cli_util.hpp

namespace {

using vmsim::test::kPartsDir;

// One pass of a ball D2 along x across a 4 x 2 mm box, z-map at 0.05 mm (81 x 41 = 3321 nodes), the program's
// path cut exactly as the reference.
fs::path write_outputs_job(const fs::path& dir, const std::string& outputs) {
  std::ofstream(dir / "cut.ngc") << "G21 G90 G94 G17\nG0 X-2 Y1 Z5\nG1 Z-0.2 F600\nG1 X6\nG0 Z5\nM30\n";
  std::ofstream(dir / "job.toml") << "[job]\nname = \"outputs\"\nmachine = \"" << kPartsDir
                                  << "machines/mikron_ucp710.toml\"\nprogram = \"cut.ngc\"\nstart_mm = [-2.0, 1.0, "
                                     "5.0]\n\n[tool]\ntype = \"ball\"\ndiameter_mm = 2.0\n\n[stock]\ntype = \"box\"\n"
                                     "min_mm = [0.0, 0.0, -1.0]\nmax_mm = [4.0, 2.0, 0.0]\n\n[removal]\nfield = "
                                     "\"zmap\"\nspacing_mm = 0.05\nmotion = \"program\"\n\n"
                                  << outputs;
  return dir / "job.toml";
}

struct Written {
  std::set<std::string> files;
  std::vector<int> vtp_levels;
  nlohmann::json report;
};

Written write_outputs_file(const core::Job& job, const sim::RunResult& r, const fs::path& dir) {
  fs::create_directories(dir);
  Written w;
  const sim::VtpWriter vtp = [&](const fs::path& f, const core::TriangleMesh&, int level) {
    std::ofstream(f) << "vtp";
    w.vtp_levels.push_back(level);
  };
  const std::vector<std::string> listed = sim::write_run_outputs(job, r, dir, vtp, &w.report);
  w.files.insert(listed.begin(), listed.end());
  std::set<std::string> on_disk;
  for (const auto& e : fs::directory_iterator(dir)) on_disk.insert(e.path().filename().string());
  EXPECT_EQ(on_disk, w.files);  // every file listed is written, and only those
  return w;
}

}  // namespace

TEST(Outputs, JobOutputsTableChoosesTheFiles) {
  TempDir tmp("vmsim_outputs_");
  const core::Job plain = core::load_job(write_outputs_job(tmp.path(), ""));
  const sim::RunResult r = sim::run_job(plain);
  ASSERT_TRUE(r.surface && r.deviation && r.part_mesh_triangles > 0);
  const core::TriangleMesh part_mesh = sim::grid_part_mesh(r);  // the run leaves it to be made on request
  ASSERT_EQ(part_mesh.triangles.rows(), r.part_mesh_triangles);
  const std::set<std::string> grids_csv = {"surface.csv", "reference.csv", "deviation.csv"};
  const std::set<std::string> grids_npy = {
      "surface.npy",        "surface.npy.json",       "deviation.npy",
      "deviation.npy.json", "deviation_vertical.npy", "deviation_vertical.npy.json"};
  const std::set<std::string> grids_x3p = {"surface.x3p", "reference.x3p", "deviation.x3p"};
  const std::set<std::string> mesh = {"part.stl", "part.vtp"};
  auto all_of = [&](std::initializer_list<std::set<std::string>> sets) {
    std::set<std::string> s;
    if (r.signals) s.insert("signals.csv");
    for (const auto& x : sets) s.insert(x.begin(), x.end());
    return s;
  };
  {  // Defaults, a small grid: everything, as before [outputs] existed; part.vtp at zlib level 1.
    const Written w = write_outputs_file(plain, r, tmp.path() / "plain");
    EXPECT_EQ(w.files, all_of({grids_csv, grids_npy, grids_x3p, mesh}));
    EXPECT_EQ(w.vtp_levels, std::vector<int>{1});
    EXPECT_EQ(w.report["outputs"]["part_mesh"]["kind"], "full");
    EXPECT_EQ(w.report["outputs"]["part_mesh"]["triangles"], part_mesh.triangles.rows());
    EXPECT_FALSE(w.report["outputs"].contains("notes"));
    // The full mesh is the run's, two triangles per cell.
    EXPECT_EQ(core::read_stl(tmp.path() / "plain" / "part.stl").triangles.rows(), part_mesh.triangles.rows());
  }
  {  // A "large" grid by the job's threshold: no CSV, no mesh, and notes naming the keys that write them.
    const core::Job job = core::load_job(write_outputs_job(tmp.path(), "[outputs]\nlarge_grid_nodes = 3000\n"));
    const Written w = write_outputs_file(job, r, tmp.path() / "large");
    EXPECT_EQ(w.files, all_of({grids_npy, grids_x3p}));
    EXPECT_EQ(w.report["outputs"]["part_mesh"]["kind"], "none");
    EXPECT_EQ(w.report["outputs"]["csv"], false);
    const std::string notes = w.report["outputs"]["notes"].dump();
    EXPECT_NE(notes.find("csv = \\\"always\\\""), std::string::npos) << notes;
    EXPECT_NE(notes.find("part_mesh = \\\"full\\\""), std::string::npos) << notes;
  }
  {  // Every key given: no grids at all, the simplified mesh, zlib level 7.
    const core::Job job = core::load_job(
        write_outputs_job(tmp.path(),
                          "[outputs]\npart_mesh = \"simplified\"\ncsv = \"never\"\nnpy = false\nx3p = false\n"
                          "mesh_tolerance_mm = 0.001\nvtp_compression_level = 7\n"));
    const Written w = write_outputs_file(job, r, tmp.path() / "chosen");
    EXPECT_EQ(w.files, all_of({mesh}));
    EXPECT_EQ(w.vtp_levels, std::vector<int>{7});
    const nlohmann::json& m = w.report["outputs"]["part_mesh"];
    EXPECT_EQ(m["kind"], "simplified");
    EXPECT_DOUBLE_EQ(m["error_bound_mm"].get<double>(), 0.002);
    // The untouched stock top either side of the pass is flat: fewer triangles than the full mesh.
    EXPECT_GT(m["flat_blocks"].get<int>(), 0);
    EXPECT_LT(m["triangles"].get<long>(), part_mesh.triangles.rows());
    EXPECT_EQ(core::read_stl(tmp.path() / "chosen" / "part.stl").triangles.rows(), m["triangles"].get<long>());
  }
  {  // Above the threshold, but asked for: csv "always" and the full mesh are written.
    const core::Job job = core::load_job(
        write_outputs_job(tmp.path(), "[outputs]\nlarge_grid_nodes = 10\ncsv = \"always\"\npart_mesh = \"full\"\n"));
    const Written w = write_outputs_file(job, r, tmp.path() / "asked");
    EXPECT_EQ(w.files, all_of({grids_csv, grids_npy, grids_x3p, mesh}));
    EXPECT_FALSE(w.report["outputs"].contains("notes"));
  }
}
