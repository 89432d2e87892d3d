#include "metrology/grid_io.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim::metrology {

void write_height_csv(const std::filesystem::path& file, const core::HeightGrid& g) {
  core::AtomicFile out(file);
  auto& s = out.stream();
  s << fmt::format("# vmsim height grid, mm; row j is y = y0 + j dy, column i is x = x0 + i dx\n");
  s << fmt::format("# x0_mm={:.9g} y0_mm={:.9g} dx_mm={:.9g} dy_mm={:.9g} nx={} ny={}\n", g.x0_mm, g.y0_mm, g.dx_mm,
                   g.dy_mm, g.nx(), g.ny());
  std::string line;
  for (Eigen::Index j = 0; j < g.ny(); ++j) {
    line.clear();
    for (Eigen::Index i = 0; i < g.nx(); ++i) {
      if (i) line += ',';
      const double z = g.z_mm(j, i);
      line += std::isfinite(z) ? fmt::format("{:.7f}", z) : "nan";
    }
    line += '\n';
    s << line;
  }
  out.commit();
}

core::HeightGrid read_height_csv(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  core::HeightGrid g;
  long nx = -1, ny = -1;
  std::string line;
  int lineno = 0;
  std::vector<double> values;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.rfind("# x0_mm=", 0) == 0) {
      if (std::sscanf(line.c_str(), "# x0_mm=%lf y0_mm=%lf dx_mm=%lf dy_mm=%lf nx=%ld ny=%ld", &g.x0_mm, &g.y0_mm,
                      &g.dx_mm, &g.dy_mm, &nx, &ny) != 6 || nx <= 0 || ny <= 0 || nx > 100000 || ny > 100000 ||
          !(g.dx_mm > 0) || !(g.dy_mm > 0))
        throw core::Error(core::located(file.string(), lineno, "bad grid header (x0_mm= y0_mm= dx_mm= dy_mm= nx= ny=)"));
      values.reserve(static_cast<std::size_t>(nx * ny));
      continue;
    }
    if (line.empty() || line[0] == '#') continue;
    if (nx < 0) throw core::Error(core::located(file.string(), lineno, "data before the grid header"));
    std::stringstream ss(line);
    std::string cell;
    long count = 0;
    while (std::getline(ss, cell, ',')) {
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      if (end == cell.c_str()) throw core::Error(core::located(file.string(), lineno, "not a number: \"" + cell + "\""));
      values.push_back(v);
      ++count;
    }
    if (count != nx) throw core::Error(core::located(file.string(), lineno, fmt::format("expected {} values, found {}", nx, count)));
    if (static_cast<long>(values.size()) > nx * ny) throw core::Error(core::located(file.string(), lineno, "more rows than ny"));
  }
  if (nx < 0) throw core::Error(file.string() + ": no grid header");
  if (static_cast<long>(values.size()) != nx * ny)
    throw core::Error(file.string() + fmt::format(": expected {} rows, found {}", ny, values.size() / static_cast<std::size_t>(nx)));
  g.z_mm = Eigen::Map<core::HeightArray>(values.data(), ny, nx);
  return g;
}

void write_height_npy(const std::filesystem::path& file, const core::HeightGrid& g) {
  // NPY 1.0: magic, version, little-endian header length, a Python dict literal padded to 64 bytes, raw data.
  std::string header = fmt::format("{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, {}), }}", g.ny(), g.nx());
  const std::size_t total = 10 + header.size() + 1;
  header += std::string((64 - total % 64) % 64, ' ');
  header += '\n';
  core::AtomicFile out(file);
  auto& s = out.stream();
  s.write("\x93NUMPY\x01\x00", 8);
  const unsigned short hl = static_cast<unsigned short>(header.size());
  const char len[2] = {static_cast<char>(hl & 0xff), static_cast<char>(hl >> 8)};
  s.write(len, 2);
  s.write(header.data(), static_cast<std::streamsize>(header.size()));
  s.write(reinterpret_cast<const char*>(g.z_mm.data()), static_cast<std::streamsize>(g.z_mm.size() * sizeof(double)));
  out.commit();
  std::filesystem::path side = file;
  side += ".json";
  core::write_file_atomic(side, fmt::format("{{\"x0_mm\": {:.9g}, \"y0_mm\": {:.9g}, \"dx_mm\": {:.9g}, \"dy_mm\": {:.9g}, "
                                            "\"nx\": {}, \"ny\": {}, \"z_unit\": \"mm\", \"row\": \"y\"}}\n",
                                            g.x0_mm, g.y0_mm, g.dx_mm, g.dy_mm, g.nx(), g.ny()));
}

}  // namespace vmsim::metrology
