#pragma once
// Tool changes (issue 24 section 1): the tools a job cuts with, which one is in the spindle at each move, and what
// each one did (report.json "tools", the marks' tool).
//
// A job gives one [tool] (it cuts every move; a program calling several T numbers is refused unless [tool]
// all_tools = true) or one [[tools]] per T number (840D programs' T="name" by name). PoseTrack::tool holds, per track
// sample, an index into job_tools(job); the removal then cuts each run of one tool with that tool's sweeps, in program
// order (removal::sweeps_from_track, sim::cut_field).
#include "core/height_grid.hpp"
#include "core/job.hpp"
#include "core/toolpath.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/marks.hpp"
#include "removal/track.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace vmsim::sim {

struct Motion;
struct Cut;

// Which tool last cut each node of a job with several tools (issue 24 section 1): per node of the z grid (z-map, or the
// tri-dexel's Z grid; row-major, nu x nv like removal::height_grid's nodes), the index into job_tools(job) of the last
// tool whose run of sweeps lowered the node's top, kUncut where none did.
struct ToolMap {
  static constexpr std::uint8_t kUncut = 255;
  int nu = 0, nv = 0;
  double cell_mm2 = 0;             // a node's cell on the z grid (du x dv): a tool's area is its nodes times this
  std::vector<std::uint8_t> tool;  // tool[j * nu + i]
  std::uint8_t at(int i, int j) const { return tool[static_cast<std::size_t>(j) * static_cast<std::size_t>(nu) + i]; }
};

// The map in the height grid's layout (rows along y, as core::HeightGrid and tool_map.npy): the tool's index, -1 where
// none cut.
metrology::IndexGrid tool_index(const ToolMap& map);

// The tools PoseTrack::tool indexes: [[tools]] in the job's order, or the one [tool] (index 0).
std::vector<core::ToolSpec> job_tools(const core::Job& job);
std::vector<removal::Tool> cutting_tools(const core::Job& job);

// Per program move, the index into job_tools(job) of the tool that cuts it. Moves before the program's first tool
// change (tool number 0) are cut by a [[tools]] with number = 0 if the job has one, else by the first tool the program
// loads. Throws core::Error naming the program file, the line and the T number (or T="name") when the job does not
// describe a tool the program changes to, or when a job's one [tool] meets several T numbers without all_tools.
std::vector<int> move_tools(const core::Job& job, const core::ToolPath& program);

// "T2" or "T=\"name\"" (840D): how the program calls tool `index` of job_tools(job).
std::string tool_label(const core::Job& job, int index);

// Per sample of a track made from a motion's setpoints or actual positions (samples past the last setpoint, while
// the axes settle, keep the last setpoint's move), the tool index. Empty for a single tool (one [tool]).
std::vector<int> sample_tools(const core::Job& job, const Motion& motion, Eigen::Index samples);

// report.json "tools": per tool its number (name), shape and size, the moves it makes (and of those, the feed
// moves), its cutting time on the setpoints (samples under it x period; absent for motion = "program"), its sweeps,
// and where the tool came from (job [tool], [[tools]], or the CL program's TLDATA/ or CUTTER/).
nlohmann::json tools_json(const core::Job& job, const Cut& cut);

// For each mark of a grid field, the index into job_tools(job) of the tool whose sweep made the surface at the
// mark's deepest point: the first sweep in program order whose interval along the vertical through (x, y) ends
// within `tolerance_mm` of the surface height there (a flat floor or wall left by several passes is credited to the
// first that reached it). -1 when no sweep made it (the mark lies on uncut stock). Why the sweep rather than the
// tool active at the nearest setpoint: the nearest setpoint in x, y may belong to a later tool passing above the
// surface (rapids, retracts, another depth); the sweep whose body bounds the material is the one that cut it.
// `surface` is the predicted surface the marks were found on (its node nearest each mark gives the height).
std::vector<int> mark_tools(const Cut& cut, const std::vector<metrology::Mark>& marks, const core::HeightGrid& surface,
                            double tolerance_mm);

}  // namespace vmsim::sim
