// A real NX CLSF file end to end on the HAAS UMC-750-like B/C machine (parts/haas_umc750/variable_axis.toml:
// APT_Variable_Axis.txt of the MECH491 post-processor course project, CC0, read from ../shared/data/real, skipped when
// absent): program -> branch-chosen inverse -> interpolator -> drives -> z-map removal. Reference: the programmed
// geometry itself. Under each programmed point P with tool axis u the ball of radius R reaches down to
// z = P.z + R (u.z - 1) at (x, y) of its centre P + R u: the machined surface there is no higher than that (plus the
// z-map's sampling of the ball's bottom and the drives' following error), and nowhere lower than the lowest such point.
// Also: units and tool taken from the job or the program, never guessed silently.
#include "core/job.hpp"
#include "sim/job_program.hpp"
#include "sim/run.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace vmsim::sim {
namespace {

namespace fs = std::filesystem;

fs::path data_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "nx_clsf_haas_umc750"; }
fs::path job_file() { return fs::path(VMSIM_SOURCE_DIR) / "parts" / "haas_umc750" / "variable_axis.toml"; }

#define SKIP_WITHOUT_DATA() \
  if (!fs::exists(data_dir())) GTEST_SKIP() << data_dir() << " is absent (the real CAM programs of ../shared)"

TEST(HaasNx, VariableAxisBallCutsWhereTheProgramPutsTheBall) {
  SKIP_WITHOUT_DATA();
  const core::Job job = core::load_job(job_file());
  const RunResult r = run_job(job);
  ASSERT_TRUE(r.surface);
  const core::HeightGrid& s = *r.surface;
  const core::ToolPath prog = read_job_program(job);
  EXPECT_TRUE(prog.warnings.empty()) << prog.warnings.front();
  const double R = job.tool.diameter_mm / 2, top = job.stock.max_mm.z();
  // Within the z-map's sampling of the ball's bottom (half a diagonal off the node: (0.35 mm)^2 / 2R) and the drives'
  // following error at 254 mm/min (micrometres); below, also the interpolation tolerance (0.01 mm).
  const double spacing = s.dx_mm, tol = 0.5 * spacing * spacing / R + 0.01;
  double lowest = top, worst_above = -1e9;
  int checked = 0;
  for (const core::Move& m : prog.moves) {
    const Eigen::Vector3d p = m.end.head<3>(), u = m.tool_axis_end->normalized();
    const Eigen::Vector3d c = p + R * u;
    const double zb = c.z() - R;
    lowest = std::min(lowest, zb);
    if (m.rapid || zb >= top - 0.05) continue;
    const auto i = static_cast<Eigen::Index>(std::lround((c.x() - s.x0_mm) / s.dx_mm));
    const auto j = static_cast<Eigen::Index>(std::lround((c.y() - s.y0_mm) / s.dy_mm));
    if (i < 1 || j < 1 || i + 1 >= s.nx() || j + 1 >= s.ny() || !s.valid(j, i)) continue;
    worst_above = std::max(worst_above, s.z_mm(j, i) - zb);
    ++checked;
  }
  double min_surface = top;
  for (Eigen::Index j = 0; j < s.ny(); ++j)
    for (Eigen::Index i = 0; i < s.nx(); ++i)
      if (s.valid(j, i)) min_surface = std::min(min_surface, s.z_mm(j, i));
  EXPECT_GT(checked, 100);
  EXPECT_LT(worst_above, tol) << "the surface stands above the programmed ball";
  EXPECT_GT(min_surface, lowest - 0.02) << "the surface lies below the lowest programmed ball";
  EXPECT_LT(min_surface, top - 1.0) << "nothing was cut";
  std::printf(
      "[ HAAS NX  ] %d programmed points under the stock top: surface at most %.4f mm above the ball's bottom "
      "(tolerance %.4f); lowest surface %.4f mm, lowest ball bottom %.4f mm\n",
      checked, worst_above, tol, min_surface, lowest);
}

// The same file through a job that gives neither the units nor the tool: a warning for the units, and the tool of
// the program's TLDATA/MILL,1.0000,0.5000,3.0000 (line 2), said so.
TEST(HaasNx, UnitsWarnedAndToolTakenFromTheProgram) {
  SKIP_WITHOUT_DATA();
  const fs::path dir = fs::temp_directory_path() / "vmsim_haas_test";
  fs::create_directories(dir);
  const fs::path jf = dir / "bare.toml";
  std::ofstream(jf) << "[job]\nmachine = \""
                    << (fs::path(VMSIM_SOURCE_DIR) / "parts/machines/haas_umc750.toml").string() << "\"\nprogram = \""
                    << (data_dir() / "APT_Variable_Axis.txt").string() << "\"\n";
  core::Job job = core::load_job(jf);
  EXPECT_FALSE(job.tool_given);
  const core::ToolPath prog = read_job_program(job);
  ASSERT_FALSE(prog.warnings.empty());
  EXPECT_NE(prog.warnings.front().find("no UNITS/"), std::string::npos) << prog.warnings.front();
  const auto note = use_program_tool(job);
  ASSERT_TRUE(note);
  EXPECT_NE(note->find("APT_Variable_Axis.txt:2:"), std::string::npos) << *note;
  EXPECT_NE(note->find("ball"), std::string::npos) << *note;
  EXPECT_EQ(job.tool.shape, core::ToolShape::Ball);
  EXPECT_DOUBLE_EQ(job.tool.diameter_mm, 1.0);  // read as mm, as the warning says
  // With the units given, the tool is in inch.
  std::ofstream(jf, std::ios::app) << "program_units = \"inch\"\n";
  core::Job inch = core::load_job(jf);
  ASSERT_TRUE(use_program_tool(inch));
  EXPECT_DOUBLE_EQ(inch.tool.diameter_mm, 25.4);
  EXPECT_DOUBLE_EQ(inch.tool.flute_length_mm, 76.2);
  // A job with [tool] keeps it: silently when it is the program's, with a note when it is a stand-in.
  core::Job given = core::load_job(job_file());
  EXPECT_FALSE(use_program_tool(given));
  core::Job stand_in = core::load_job(fs::path(VMSIM_SOURCE_DIR) / "parts" / "haas_umc750" / "chamfer_ball.toml");
  const auto differs = use_program_tool(stand_in);
  ASSERT_TRUE(differs);
  EXPECT_NE(differs->find("APT_code.txt:2: the program's tool is D19.05 R3.048 mm; the job's [tool] D19.05 R9.525 mm"),
            std::string::npos)
      << *differs;
  EXPECT_EQ(stand_in.tool.shape, core::ToolShape::Ball);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vmsim::sim
