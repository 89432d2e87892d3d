#include "sim/tools.hpp"

#include "core/error.hpp"
#include "sim/pipeline.hpp"
#include "sim/run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace vmsim::sim {

namespace {

// The 840D reader numbers T="name" tools 1, 2, ... (core::ToolPath::tool_names); other programs' numbers are T words.
std::string program_tool_name(const core::ToolPath& program, int number) {
  if (number >= 1 && static_cast<std::size_t>(number) <= program.tool_names.size())
    return program.tool_names[static_cast<std::size_t>(number) - 1];
  return {};
}

const core::ProgramTool* program_tool(const core::ToolPath& program, int number) {
  for (const core::ProgramTool& t : program.program_tools)
    if (t.number == number) return &t;
  return nullptr;
}

// A CL program's tools are also named by their geometry and the record that gives it (its number may be vmsim's).
std::string program_label(const core::ToolPath& program, int number) {
  const std::string name = program_tool_name(program, number);
  if (!name.empty()) return fmt::format("T=\"{}\"", name);
  if (const core::ProgramTool* t = program_tool(program, number))
    return fmt::format("T{} (D{:.4g} R{:.4g} mm of line {}{})", number, t->diameter_mm, t->corner_radius_mm, t->line,
                       t->numbered_by_program ? "" : ", numbered in order of appearance");
  return fmt::format("T{}", number);
}

const char* shape_name(core::ToolShape s) {
  return s == core::ToolShape::Ball ? "ball" : s == core::ToolShape::Flat ? "flat" : "bullnose";
}

}  // namespace

metrology::IndexGrid tool_index(const ToolMap& map) {
  metrology::IndexGrid out(map.nv, map.nu);
  for (int j = 0; j < map.nv; ++j)
    for (int i = 0; i < map.nu; ++i)
      out(j, i) = map.at(i, j) == ToolMap::kUncut ? std::int8_t{-1} : static_cast<std::int8_t>(map.at(i, j));
  return out;
}

std::vector<core::ToolSpec> job_tools(const core::Job& job) {
  if (!job.tools.empty()) return job.tools;
  return {job.tool};
}

std::vector<removal::Tool> cutting_tools(const core::Job& job) {
  std::vector<removal::Tool> out;
  for (const core::ToolSpec& t : job_tools(job)) out.push_back(removal::make_tool(t));
  return out;
}

std::string tool_label(const core::Job& job, int index) {
  if (job.tools.empty()) return "[tool]";
  const core::ToolSpec& t = job.tools.at(static_cast<std::size_t>(index));
  return t.number >= 0 ? fmt::format("T{}", t.number) : fmt::format("T=\"{}\"", t.name);
}

std::vector<int> move_tools(const core::Job& job, const core::ToolPath& program) {
  const std::vector<core::Move>& moves = program.moves;
  std::vector<int> out(moves.size(), 0);
  // The T numbers the program calls, each with the first line that moves under it.
  std::map<int, int> first_line;
  for (const core::Move& m : moves)
    if (m.tool_number != 0) first_line.emplace(m.tool_number, m.source_line);
  if (job.tools.empty()) {
    if (first_line.size() > 1 && !job.tool_all_numbers) {
      std::string called;
      for (const auto& [n, line] : first_line)
        called += fmt::format("{}{} (line {})", called.empty() ? "" : ", ", program_label(program, n), line);
      throw core::Error(fmt::format(
          "{}: [tool] describes one tool but the program {} changes between {} tools: {}; give one [[tools]] per tool "
          "(number, type, diameter_mm, ...), or [tool] all_tools = true to cut every move with this one tool",
          job.file.string(), program.source_path, first_line.size(), called));
    }
    return out;  // the one tool, index 0
  }
  // T number (or 840D name) -> index into job.tools.
  auto find = [&](int number) -> int {
    const std::string name = program_tool_name(program, number);
    for (std::size_t k = 0; k < job.tools.size(); ++k) {
      const core::ToolSpec& t = job.tools[k];
      if (!name.empty() ? t.name == name : t.number == number) return static_cast<int>(k);
    }
    return -1;
  };
  auto described = [&] {
    std::string s;
    for (std::size_t k = 0; k < job.tools.size(); ++k) s += (k ? ", " : "") + tool_label(job, static_cast<int>(k));
    return s;
  };
  std::map<int, int> index_of;
  for (const auto& [n, line] : first_line) {
    const int k = find(n);
    if (k < 0)
      throw core::Error(fmt::format(
          "{}:{}: the program changes to {}, which the job {} does not describe (its [[tools]]: {}; expected a "
          "[[tools]] with {})",
          program.source_path, line, program_label(program, n), job.file.string(), described(),
          program_tool_name(program, n).empty() ? fmt::format("number = {}", n)
                                                : fmt::format("name = \"{}\"", program_tool_name(program, n))));
    index_of[n] = k;
  }
  // Before the first tool change: a [[tools]] numbered 0, else the first tool the program loads.
  int before_first = -1;
  for (std::size_t k = 0; k < job.tools.size(); ++k)
    if (job.tools[k].number == 0) before_first = static_cast<int>(k);
  for (const core::Move& m : moves)
    if (before_first < 0 && m.tool_number != 0) before_first = index_of.at(m.tool_number);
  if (before_first < 0 && !moves.empty())
    throw core::Error(fmt::format(
        "{}: the program {} never changes tools (no T... M6), so none of the job's [[tools]] ({}) is in the spindle; "
        "expected [tool] for a single-tool job, or a [[tools]] with number = 0",
        job.file.string(), program.source_path, described()));
  for (std::size_t k = 0; k < moves.size(); ++k)
    out[k] = moves[k].tool_number == 0 ? before_first : index_of.at(moves[k].tool_number);
  return out;
}

std::vector<int> sample_tools(const core::Job& job, const Motion& motion, Eigen::Index samples) {
  if (job.tools.empty()) return {};
  const std::vector<int> per_move = move_tools(job, motion.program);
  const Eigen::ArrayXi& mi = motion.interp.setpoints.move_index;
  std::vector<int> out(static_cast<std::size_t>(samples), per_move.empty() ? 0 : per_move.front());
  if (mi.size() == 0) return out;
  for (Eigen::Index k = 0; k < samples; ++k) {
    const int m = mi[std::min(k, mi.size() - 1)];
    if (m >= 0 && static_cast<std::size_t>(m) < per_move.size()) out[static_cast<std::size_t>(k)] = per_move[m];
  }
  return out;
}

nlohmann::json tools_json(const core::Job& job, const Cut& cut) {
  const std::vector<core::ToolSpec> tools = job_tools(job);
  const core::ToolPath& program = cut.motion.program;
  const std::vector<int> per_move = move_tools(job, program);
  const std::size_t n = tools.size();
  std::vector<std::size_t> moves(n, 0), feed_moves(n, 0), sweeps(n, 0);
  std::vector<double> time_s(n, 0.0);
  for (std::size_t k = 0; k < per_move.size(); ++k) {
    const auto t = static_cast<std::size_t>(per_move[k]);
    ++moves[t];
    if (!program.moves[k].rapid) ++feed_moves[t];
  }
  const core::Setpoints& sp = cut.motion.interp.setpoints;
  const bool timed = job.removal.motion != core::RemovalSpec::Motion::Program && sp.samples() > 0;
  if (timed) {
    // A sample's period is spent on its move (the cycle time is (samples - 1) x period; the last sample adds none).
    for (Eigen::Index k = 0; k + 1 < sp.samples(); ++k) {
      const int m = sp.move_index[k];
      const std::size_t t = m >= 0 && static_cast<std::size_t>(m) < per_move.size()
                                ? static_cast<std::size_t>(per_move[static_cast<std::size_t>(m)])
                                : (per_move.empty() ? 0 : static_cast<std::size_t>(per_move.front()));
      time_s[t] += sp.period_s;
    }
  }
  for (const removal::TrackSweeps::Run& r : cut.sweeps.runs) sweeps[static_cast<std::size_t>(r.tool)] += r.count;
  // Per tool, the nodes it cut last times a node's cell.
  std::vector<std::size_t> last_cut(n, 0);
  if (cut.tool_map)
    for (const std::uint8_t t : cut.tool_map->tool)
      if (t < n) ++last_cut[t];
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t t = 0; t < n; ++t) {
    const core::ToolSpec& s = tools[t];
    nlohmann::json j = {{"tool", job.tools.empty() ? "[tool]" : tool_label(job, static_cast<int>(t))},
                        {"type", shape_name(s.shape)},
                        {"diameter_mm", s.diameter_mm},
                        {"corner_radius_mm", s.corner_radius_mm},
                        {"flute_length_mm", s.flute_length_mm},
                        {"length_mm", s.length_mm},
                        {"moves", moves[t]},
                        {"feed_moves", feed_moves[t]},
                        {"sweeps", sweeps[t]}};
    if (!job.tools.empty()) {
      if (s.number >= 0) j["number"] = s.number;
      if (!s.name.empty()) j["name"] = s.name;
      // A CL program's tool: the records that start each stretch of moves it cuts.
      if (const core::ProgramTool* pt = s.name.empty() ? program_tool(program, s.number) : nullptr)
        j["program_lines"] = pt->stretch_lines;
    }
    if (timed) j["time_s"] = time_s[t];
    if (cut.tool_map) j["last_cut_area_mm2"] = static_cast<double>(last_cut[t]) * cut.tool_map->cell_mm2;
    list.push_back(j);
  }
  // The program's tools (sim::use_program_tool) fill job.tools too: tool_from_program says they are its.
  const std::string source = !job.tool_from_program.empty() ? "program " + job.tool_from_program
                             : !job.tools.empty()           ? "job [[tools]]"
                             : job.tool_given               ? "job [tool]"
                                                            : "default (no [tool] in the job)";
  nlohmann::json out = {{"source", source}, {"list", list}};
  if (job.tools.empty() && job.tool_all_numbers) out["all_tools"] = true;
  return out;
}

std::vector<int> mark_tools(const Cut& cut, const std::vector<metrology::Mark>& marks, const core::HeightGrid& surface,
                            double tolerance_mm) {
  std::vector<int> out(marks.size(), -1);
  const std::vector<removal::SweptTool>& sweeps = cut.sweeps.sweeps;
  // The tool of each sweep, from the runs.
  std::vector<int> tool_of(sweeps.size(), 0);
  for (const removal::TrackSweeps::Run& r : cut.sweeps.runs)
    std::fill(tool_of.begin() + static_cast<std::ptrdiff_t>(r.first),
              tool_of.begin() + static_cast<std::ptrdiff_t>(r.first + r.count), r.tool);
  const Eigen::Vector3d down(0, 0, -1);
  for (std::size_t m = 0; m < marks.size(); ++m) {
    const double x = marks[m].x_mm, y = marks[m].y_mm;
    const auto i = static_cast<Eigen::Index>(std::lround((x - surface.x0_mm) / surface.dx_mm));
    const auto j = static_cast<Eigen::Index>(std::lround((y - surface.y0_mm) / surface.dy_mm));
    if (i < 0 || j < 0 || i >= surface.nx() || j >= surface.ny() || !surface.valid(j, i)) continue;
    const double h = surface.z_mm(j, i);
    for (std::size_t k = 0; k < sweeps.size(); ++k) {
      Eigen::Vector3d lo, hi;
      sweeps[k].bounds(lo, hi);
      if (x < lo.x() || x > hi.x() || y < lo.y() || y > hi.y() || lo.z() > h + tolerance_mm ||
          hi.z() < h - tolerance_mm)
        continue;
      const Eigen::Vector3d o(x, y, hi.z() + 1.0);
      double t0, t1;
      if (!removal::ray_interval(sweeps[k], o, down, t0, t1)) continue;
      if (std::abs((o.z() - t1) - h) <= tolerance_mm) {
        out[m] = tool_of[k];
        break;
      }
    }
  }
  return out;
}

}  // namespace vmsim::sim
