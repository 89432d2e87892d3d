#include "methods/feedplan_file.hpp"
#include "core/regular_file.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

namespace vmsim::methods {

namespace {

constexpr const char* kMagic = "# vmsim feed plan 1";
constexpr const char* kHeader = "s_mm,feed_ceiling_mm_per_s,x_mm,y_mm,z_mm";
constexpr double kPathTolerance = 1e-6;  // mm: the file holds the points to 1e-9 mm

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::stringstream ss(line);
  while (std::getline(ss, cell, ',')) {
    while (!cell.empty() && cell.back() == ' ') cell.pop_back();
    while (!cell.empty() && cell.front() == ' ') cell.erase(cell.begin());
    cells.push_back(cell);
  }
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

// A finite number, or nothing.
bool parse_number(const std::string& text, double& v) {
  if (text.empty()) return false;
  char* end = nullptr;
  v = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0' && std::isfinite(v);
}

}  // namespace

void write_feed_plan(const std::filesystem::path& file, const motion::FeedCeiling& ceiling,
                     const motion::SmoothPath& path, double period_s, const std::string& job_name,
                     const std::vector<std::string>& comments) {
  ceiling.check();
  if (ceiling.empty()) throw core::Error(file.string() + ": a feed plan needs at least one point");
  core::AtomicFile out(file);
  auto& s = out.stream();
  s << kMagic << ": a feed ceiling along the path the interpolator follows (Chen et al. 2016, vmsim plan-feed)\n";
  s << "# job=" << job_name << "\n";
  s << fmt::format("# period_s={:.17g}\n# path_length_mm={:.17g}\n# points={}\n", period_s, path.length,
                   ceiling.s_mm.size());
  // Only a followed profile says so: a ceiling's file stays as it was.
  if (ceiling.follow) s << "# follow=1\n";
  for (const std::string& c : comments) s << "# " << c << "\n";
  s << kHeader << "\n";
  motion::SmoothPath::Cursor cursor;
  std::string line;
  for (std::size_t i = 0; i < ceiling.s_mm.size(); ++i) {
    const core::Vec6 p = path.point(std::min(ceiling.s_mm[i], path.length), cursor);
    line = fmt::format("{:.17g},{:.17g},{:.9f},{:.9f},{:.9f}\n", ceiling.s_mm[i], ceiling.feed_mm_per_s[i], p[0], p[1],
                       p[2]);
    s << line;
  }
  out.commit();
}

motion::FeedCeiling read_feed_plan(const std::filesystem::path& file, const motion::SmoothPath& path, double period_s) {
  core::require_regular_file(file);
  const std::string f = file.string();
  std::ifstream in(file);
  if (!in) throw core::Error(f + ": cannot open the feed plan");
  std::string line;
  int lineno = 0;
  std::map<std::string, std::string> meta;
  bool magic = false, header = false;
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (line[0] == '#') {
      if (lineno == 1 && line.rfind(kMagic, 0) == 0) magic = true;
      const auto eq = line.find('=');
      if (eq != std::string::npos && line.find(' ', 2) > eq) meta[line.substr(2, eq - 2)] = line.substr(eq + 1);
      continue;
    }
    if (line != kHeader)
      throw core::Error(core::located(f, lineno, fmt::format("expected the column header \"{}\"", kHeader)));
    header = true;
    break;
  }
  if (!magic)
    throw core::Error(core::located(f, 1,
                                    std::string("not a vmsim feed plan (expected a first line \"") + kMagic +
                                        ": ...\", as vmsim plan-feed writes)"));
  if (!header) throw core::Error(f + fmt::format(": no column header ({})", kHeader));
  const int head_line = lineno;
  const auto number = [&](const std::string& key) {
    const auto it = meta.find(key);
    if (it == meta.end()) throw core::Error(f + ": the header has no '# " + key + "=' line");
    double v = 0;
    if (!parse_number(it->second, v)) throw core::Error(f + ": '# " + key + "=" + it->second + "' is not a number");
    return v;
  };
  const double te = number("period_s"), length = number("path_length_mm"), points = number("points");
  if (std::abs(te - period_s) > 1e-12 * period_s)
    throw core::Error(fmt::format("{}: the plan is for Te = {} s, the job interpolates at Te = {} s", f, te, period_s));
  if (std::abs(length - path.length) > kPathTolerance)
    throw core::Error(
        fmt::format("{}: the plan was made for a path of {:.6f} mm, the job's path is {:.6f} mm long: it "
                    "was planned for another program, curve or tolerance (run vmsim plan-feed on this job "
                    "again)",
                    f, length, path.length));
  if (!(points >= 1 && points == std::floor(points)))
    throw core::Error(f + fmt::format(": '# points={}': expected a whole number >= 1", points));

  motion::FeedCeiling c;
  if (meta.count("follow")) {
    const double follow = number("follow");
    if (follow != 0.0 && follow != 1.0) throw core::Error(f + ": '# follow=' expects 0 or 1");
    c.follow = follow == 1.0;
  }
  motion::SmoothPath::Cursor cursor;
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (static_cast<double>(c.s_mm.size()) >= points)
      throw core::Error(core::located(f, lineno, fmt::format("more than the {} points the header announces", points)));
    const std::vector<std::string> cells = split(line);
    if (cells.size() != 5)
      throw core::Error(core::located(f, lineno, fmt::format("{} cells, expected 5", cells.size())));
    double v[5];
    for (int j = 0; j < 5; ++j)
      if (!parse_number(cells[static_cast<std::size_t>(j)], v[j]))
        throw core::Error(core::located(
            f, lineno, fmt::format("cell {} '{}' is not a number", j + 1, cells[static_cast<std::size_t>(j)])));
    if (!(v[1] > 0) && !(c.follow && v[1] == 0.0))
      throw core::Error(core::located(
          f, lineno,
          fmt::format("feed ceiling {} mm/s: expected > 0 (0 only at single points of a followed profile)", v[1])));
    if (!c.s_mm.empty() && !(v[0] > c.s_mm.back()))
      throw core::Error(core::located(
          f, lineno, fmt::format("s = {} mm: expected larger than the line before's {} mm", v[0], c.s_mm.back())));
    if (v[0] < -kPathTolerance || v[0] > path.length + kPathTolerance)
      throw core::Error(
          core::located(f, lineno, fmt::format("s = {} mm lies off the job's path (0 .. {} mm)", v[0], path.length)));
    const core::Vec6 p = path.point(std::clamp(v[0], 0.0, path.length), cursor);
    const double d = std::hypot(p[0] - v[2], p[1] - v[3], p[2] - v[4]);
    if (d > kPathTolerance)
      throw core::Error(core::located(
          f, lineno,
          fmt::format(
              "the plan's point ({}, {}, {}) at s = {} mm is {:.6g} mm from the job's path there: it was planned "
              "for another path (run vmsim plan-feed on this job again)",
              cells[2], cells[3], cells[4], cells[0], d)));
    c.s_mm.push_back(v[0]);
    c.feed_mm_per_s.push_back(v[1]);
  }
  if (static_cast<double>(c.s_mm.size()) != points)
    throw core::Error(
        core::located(f, head_line, fmt::format("{} points, the header announces {}", c.s_mm.size(), points)));
  try {
    c.check();
  } catch (const core::Error& e) {
    throw core::Error(f + ": " + e.what());
  }
  return c;
}

}  // namespace vmsim::methods
