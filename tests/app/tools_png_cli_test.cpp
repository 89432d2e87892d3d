// tools.png (issue 24 section 1: the pictures say which tool cut where): `vmsim run` draws it beside part.png for a
// job with several tools, report.json gives each tool's last_cut_area_mm2 and report.html's tools section shows the
// picture; a single-tool job draws none. Reference: the two-slot CL program of tests/sim/cl_tool_changes_test.cpp
// (two TLDATA/ tools), whose map itself tests/sim/tool_map_test.cpp checks against the slots' analytic shapes; here
// the files a user gets.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include "render/image.hpp"
#include "tests/app/cli_util.hpp"
#include "tests/test_machines.hpp"

namespace {

namespace fs = std::filesystem;

using vmsim::test::kXyzTestMill;

const char* kTpngProgram =
    "UNITS/MM\nTLDATA/MILL,6.0000,0.0000,20.0000,0.0000,0.0000\nFEDRAT/MMPM,600\nGOTO/-15,-5,5\nGOTO/-15,-5,-1\n"
    "GOTO/15,-5,-1\nRAPID\nGOTO/15,-5,5\nTLDATA/MILL,4.0000,0.0000,20.0000,0.0000,0.0000\nRAPID\nGOTO/5,-15,5\n"
    "GOTO/5,-15,-2\nGOTO/5,15,-2\nRAPID\nGOTO/5,15,5\nFINI\n";

std::string tpng_job(const std::string& tools) {
  return "[job]\nname = \"two_slots\"\nmachine = \"machine.toml\"\nprogram = \"two.cl\"\n" + tools +
         "[stock]\ntype = \"box\"\nmin_mm = [-20.0, -20.0, -5.0]\nmax_mm = [20.0, 20.0, 0.0]\n"
         "[interpolation]\nperiod_ms = 1\ntolerance_mm = 0.005\n"
         "[removal]\nfield = \"zmap\"\nspacing_mm = 0.2\nmotion = \"program\"\n[reference]\nkind = \"none\"\n";
}

// The two-slot job (its program's two tools) in tmp, run into out with 480 x 360 pictures.
vmsim_test::CliRun run_two_slots(const vmsim_test::TempDir& tmp, const fs::path& out) {
  vmsim_test::write_file(tmp.path() / "machine.toml", kXyzTestMill);
  vmsim_test::write_file(tmp.path() / "two.cl", kTpngProgram);
  vmsim_test::write_file(tmp.path() / "two.toml", tpng_job(""));
  return vmsim_test::run_vmsim(
      "run '" + (tmp.path() / "two.toml").string() + "' -o '" + out.string() + "' --image-size 480x360", tmp);
}

TEST(ToolsPngCli, SeveralToolsDrawToolsPngAndOneToolDoesNot) {
  vmsim_test::TempDir tmp("vmsim_tools_png_");
  const fs::path out = tmp.path() / "out";
  const vmsim_test::CliRun r = run_two_slots(tmp, out);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(out / "images" / "part.png")) << r.out;
  EXPECT_TRUE(fs::exists(out / "images" / "tools.png")) << r.out;
  const nlohmann::json rep = vmsim_test::read_json(out / "report.json");
  const nlohmann::json& list = rep["tools"]["list"];
  ASSERT_EQ(list.size(), 2u);
  // Slot 2 (D4, 4 x 30 mm with round ends) lies whole in the stock: its area to within a cell band of its perimeter.
  EXPECT_NEAR(list[1]["last_cut_area_mm2"].get<double>(), 4.0 * 30.0 + std::acos(-1.0) * 4.0, 0.5 * 0.2 * 72.6);
  EXPECT_GT(list[0]["last_cut_area_mm2"].get<double>(), 0.0);
  const std::string html = vmsim_test::slurp(out / "report.html");
  EXPECT_NE(html.find("<img src=\"images/tools.png\""), std::string::npos);
  EXPECT_NE(html.find("last cut area"), std::string::npos);

  // One tool for both slots: no tools.png, no last_cut_area_mm2.
  vmsim_test::write_file(tmp.path() / "one.toml",
                         tpng_job("[tool]\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 20.0\n"
                                  "all_tools = true\n"));
  const fs::path out1 = tmp.path() / "out1";
  const vmsim_test::CliRun r1 = vmsim_test::run_vmsim(
      "run '" + (tmp.path() / "one.toml").string() + "' -o '" + out1.string() + "' --image-size 480x360", tmp);
  ASSERT_EQ(r1.code, 0) << r1.err;
  EXPECT_TRUE(fs::exists(out1 / "images" / "part.png")) << r1.out;
  EXPECT_FALSE(fs::exists(out1 / "images" / "tools.png"));
  EXPECT_FALSE(vmsim_test::read_json(out1 / "report.json")["tools"]["list"][0].contains("last_cut_area_mm2"));
  EXPECT_EQ(vmsim_test::slurp(out1 / "report.html").find("tools.png"), std::string::npos);
}

// tools.png's data is written (tool_map.npy, numpy's int8 format) and `vmsim render` redraws the picture from the
// directory alone: the same pixels as the run drew (the surface read back bit for bit from surface.csv).
TEST(ToolsPngCli, RenderRedrawsToolsPngFromToolMapNpy) {
  vmsim_test::TempDir tmp("vmsim_tools_render_");
  const fs::path out = tmp.path() / "out";
  const vmsim_test::CliRun r = run_two_slots(tmp, out);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json files = vmsim_test::read_json(out / "report.json")["files"];
  EXPECT_NE(std::find(files.begin(), files.end(), "tool_map.npy"), files.end()) << files.dump();
  EXPECT_NE(std::find(files.begin(), files.end(), "tool_map.npy.json"), files.end()) << files.dump();

  const fs::path again = tmp.path() / "again";
  const vmsim_test::CliRun rr =
      vmsim_test::run_vmsim("render '" + out.string() + "' -o '" + again.string() + "' --size 480x360", tmp);
  ASSERT_EQ(rr.code, 0) << rr.err;
  ASSERT_TRUE(fs::exists(again / "tools.png")) << rr.out;
  const vmsim::render::Image a = vmsim::render::read_png(out / "images" / "tools.png");
  const vmsim::render::Image b = vmsim::render::read_png(again / "tools.png");
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  EXPECT_TRUE(a.rgb == b.rgb) << "vmsim render drew another tools.png than vmsim run";

  // A one-tool run into the same picture folder: no tool_map.npy, and the stale tools.png goes.
  vmsim_test::write_file(tmp.path() / "one.toml",
                         tpng_job("[tool]\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 20.0\n"
                                  "all_tools = true\n"));
  const fs::path out1 = tmp.path() / "out1";
  ASSERT_EQ(vmsim_test::run_vmsim("run '" + (tmp.path() / "one.toml").string() + "' -o '" + out1.string() +
                                      "' --no-render",
                                  tmp)
                .code,
            0);
  EXPECT_FALSE(fs::exists(out1 / "tool_map.npy"));
  const vmsim_test::CliRun r1 =
      vmsim_test::run_vmsim("render '" + out1.string() + "' -o '" + again.string() + "' --size 480x360", tmp);
  ASSERT_EQ(r1.code, 0) << r1.err;
  EXPECT_TRUE(fs::exists(again / "part.png"));
  EXPECT_FALSE(fs::exists(again / "tools.png"));
}

}  // namespace
