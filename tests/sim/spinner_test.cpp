// The real NX-posted 840D program of the coordinate-system cube (Zenodo 10.5281/zenodo.15735480, Scientific Data
// 10.1038/s41597-025-05294-0, CC BY 4.0) on the Spinner U5-620 machine file, through the job as `vmsim run` reads it
// (sim::read_job_program: the reader asks the machine's kinematics at TRAORI/TRAFOOF). References: the program's own
// frames (the post writes B/C and AROT independently; the frame's Z must be the tool axis the swivel gives) and the
// programmed tip (the axes the reader and the chain compute must put the tip back there). Skipped without
// ../shared/data/real.
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/sinumerik.hpp"
#include "sim/job_program.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <regex>

namespace vmsim::sim {
namespace {

namespace fs = std::filesystem;

TEST(SpinnerU5620, ThreePlusTwoToolAxesAreTheFramesAndTheAxesJoin) {
  const fs::path job_file = fs::path(VMSIM_SOURCE_DIR) / "parts" / "spinner_u5_620" / "achskreuz.toml";
  if (!fs::exists(fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "spinner_u5-620_840d"))
    GTEST_SKIP() << "../shared/data/real is absent (the real CAM programs)";
  const core::Job job = core::load_job(job_file);
  const core::ToolPath path = read_job_program(job);
  const auto kin = motion::make_kinematics(job.machine);
  EXPECT_EQ(kin->family(), motion::KinematicFamily::TableTable);

  // The frame's Z in force at each line, from the reader's frame comments (read without a machine: the frames do
  // not depend on it).
  program::SinumerikOptions o;
  o.no_motion_mcodes = job.no_motion_mcodes;
  const program::SinumerikResult bare = program::interpret_sinumerik(job.program_file, o);
  std::vector<std::pair<int, Eigen::Vector3d>> frames;
  const std::regex z(R"(z axis \(([-0-9.]+), ([-0-9.]+), ([-0-9.]+)\))");
  for (const program::CanonCall& c : bare.canon) {
    std::smatch m;
    if (std::regex_search(c.text, m, z))
      frames.emplace_back(c.source_line, Eigen::Vector3d(std::stod(m[1]), std::stod(m[2]), std::stod(m[3])));
  }
  ASSERT_EQ(path.moves.size(), bare.path.moves.size());

  int checked = 0;
  double worst = 0;
  for (const core::Move& m : path.moves) {
    if (!m.tcp) continue;
    Eigen::Vector3d frame_z = Eigen::Vector3d::UnitZ();
    for (const auto& [line, zz] : frames)
      if (line < m.source_line) frame_z = zz;
    Eigen::VectorXd q(static_cast<Eigen::Index>(job.machine.axes.size()));
    for (std::size_t i = 0; i < job.machine.axes.size(); ++i)
      q[static_cast<Eigen::Index>(i)] = m.end[job.machine.axes[i].program_axis];
    // the rotary axes as programmed, the linear ones wherever: the tool axis depends on B and C alone
    const Eigen::Vector3d axis = kin->forward(q, 0.0).axis;
    worst = std::max(worst, (axis - frame_z).norm());
    ++checked;
  }
  EXPECT_GT(checked, 1500);
  EXPECT_LT(worst, 1e-4) << "a 3+2 operation's frame Z is not the tool axis its B and C give";

  // Every move through the chain: within the travels, joined in axis space (TRAORI/TRAFOOF switches included), and
  // each TCP move's axes put the tip where the program's frames put it.
  const core::ToolPath axes = motion::toolpath_in_axis_space(path, job.machine);
  ASSERT_EQ(axes.moves.size(), path.moves.size());
  double tip_error = 0;
  for (std::size_t k = 0; k < axes.moves.size(); ++k) {
    if (!path.moves[k].tcp) continue;
    Eigen::VectorXd q(static_cast<Eigen::Index>(job.machine.axes.size()));
    for (std::size_t i = 0; i < job.machine.axes.size(); ++i)
      q[static_cast<Eigen::Index>(i)] = axes.moves[k].end[job.machine.axes[i].program_axis];
    tip_error = std::max(tip_error, (kin->forward(q, 0.0).tip_mm - path.moves[k].end.head<3>()).norm());
  }
  EXPECT_LT(tip_error, 1e-9);
  std::printf("[ SPINNER  ] %d TCP moves: tool axis vs frame Z at most %.2e; tip through the chain within %.2e mm\n",
              checked, worst, tip_error);
}

}  // namespace
}  // namespace vmsim::sim
