#include "metrology/grid_io.hpp"
#include "metrology/reader_common.hpp"
#include "core/units.hpp"
#include "core/regular_file.hpp"

#include "core/atomic_file.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim::metrology {

namespace {

using core::units::kNaN;
// Larger grids than this are surely a typo or a hostile header (2^28 nodes = 2 GiB of heights).
constexpr long long kMaxNodes = 1LL << 28;

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Splits a data line at blanks, tabs, commas and semicolons.
void split_fields(const std::string& line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  const auto sep = [](char c) { return c == ' ' || c == '\t' || c == ',' || c == ';' || c == '\r'; };
  while (i < line.size()) {
    while (i < line.size() && sep(line[i])) ++i;
    const std::size_t b = i;
    while (i < line.size() && !sep(line[i])) ++i;
    if (i > b) out.emplace_back(line.data() + b, i - b);
  }
}

bool is_nan_token(std::string_view t) {
  const std::string l = lower(std::string(t));
  return l == "nan" || l == "-nan" || l == "+nan" || l == "bad" || l == "nodata";
}

// A height or coordinate in the file's unit (10^pow10 m) as mm; NaN for "nan".
std::optional<double> value_mm(std::string_view t, int pow10) {
  if (is_nan_token(t)) return kNaN;
  return parse_decimal_scaled(t, pow10 + 3);
}

}  // namespace

void write_height_csv(const std::filesystem::path& file, const core::HeightGrid& g) {
  core::CsvWriter out(file);
  out.comment("vmsim height grid, mm; row j is y = y0 + j dy, column i is x = x0 + i dx");
  out.comment(fmt::format("x0_mm={} y0_mm={} dx_mm={} dy_mm={} nx={} ny={}", g.x0_mm, g.y0_mm, g.dx_mm, g.dy_mm, g.nx(),
                          g.ny()));
  // Rows into one buffer, written about a megabyte at a time (issue 21: a string per number was half this write).
  std::string buf;
  buf.reserve((1 << 20) + 24 * static_cast<std::size_t>(g.nx()));
  for (Eigen::Index j = 0; j < g.ny(); ++j) {
    for (Eigen::Index i = 0; i < g.nx(); ++i) {
      if (i) buf += ',';
      const double z = g.z_mm(j, i);
      if (std::isfinite(z))
        core::append_shortest(buf, z);  // shortest digits that read back as the same double
      else
        buf += "nan";
    }
    buf += '\n';
    if (buf.size() >= (1 << 20) || j + 1 == g.ny()) {
      out.stream().write(buf.data(), static_cast<std::streamsize>(buf.size()));
      buf.clear();
    }
  }
  out.commit();
}

core::HeightGrid read_height_csv(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  return read_height_csv(in, file.string());
}

core::HeightGrid read_height_csv(std::istream& is, const std::string& file_name) {
  core::CsvReader in(is, file_name, core::CsvReader::Header::None);
  core::HeightGrid g;
  long nx = -1, ny = -1;
  std::vector<double> values;
  std::size_t headers = 0;
  // The grid header: "# x0_mm=... ny=..." among the '#' lines before the first row (and no second one after it).
  auto grid_header = [&](std::size_t from) {
    const std::vector<core::CsvComment>& cs = in.comments();
    for (; from < cs.size(); ++from) {
      const core::CsvComment& c = cs[from];
      if (c.text.rfind("# x0_mm=", 0) != 0) continue;
      if (nx >= 0) throw in.error("a second grid header", c.line);
      if (std::sscanf(c.text.c_str(), "# x0_mm=%lf y0_mm=%lf dx_mm=%lf dy_mm=%lf nx=%ld ny=%ld", &g.x0_mm, &g.y0_mm,
                      &g.dx_mm, &g.dy_mm, &nx, &ny) != 6 ||
          nx <= 0 || ny <= 0 || nx > 100000 || ny > 100000 || static_cast<long long>(nx) * ny > kMaxNodes ||
          !(g.dx_mm > 0) || !(g.dy_mm > 0) || !std::isfinite(g.dx_mm) || !std::isfinite(g.dy_mm) ||
          !std::isfinite(g.x0_mm) || !std::isfinite(g.y0_mm))
        throw in.error("bad grid header (x0_mm= y0_mm= dx_mm= dy_mm= nx= ny=)", c.line);
      // The values come with the rows; the header's size alone does not get to allocate.
      values.reserve(static_cast<std::size_t>(std::min<long long>(static_cast<long long>(nx) * ny, 1 << 20)));
    }
    return from;
  };
  while (in.next()) {
    headers = grid_header(headers);
    if (nx < 0) throw in.error("data before the grid header");
    if (static_cast<long>(in.cells()) != nx)
      throw in.error(fmt::format("expected {} values, found {}", nx, in.cells()));
    for (std::size_t c = 0; c < in.cells(); ++c) {
      const auto v = value_mm(in.cell(c), -3);
      if (!v) throw in.error("not a number: \"" + std::string(in.cell(c).substr(0, 40)) + "\"");
      values.push_back(std::isfinite(*v) ? *v : kNaN);
    }
    if (static_cast<long>(values.size()) > nx * ny) throw in.error("more rows than ny");
  }
  grid_header(headers);
  if (nx < 0) throw core::Error(file_name + ": no grid header");
  if (static_cast<long>(values.size()) != nx * ny)
    throw core::Error(file_name +
                      fmt::format(": expected {} rows, found {}", ny, values.size() / static_cast<std::size_t>(nx)));
  g.z_mm = Eigen::Map<core::HeightArray>(values.data(), ny, nx);
  return g;
}

namespace {

// The NPY 1.0 header (magic, version, little-endian length, a Python dict literal padded so the data start on a
// 64-byte boundary), as numpy.save writes it. NumPy's format is small and fixed: Debian has no C++ library for it.
void write_npy_header(std::ostream& s, const std::string& descr, Eigen::Index ny, Eigen::Index nx) {
  std::string header = fmt::format("{{'descr': '{}', 'fortran_order': False, 'shape': ({}, {}), }}", descr, ny, nx);
  const std::size_t total = 10 + header.size() + 1;
  header += std::string((64 - total % 64) % 64, ' ');
  header += '\n';
  s.write("\x93NUMPY\x01\x00", 8);
  const unsigned short hl = static_cast<unsigned short>(header.size());
  const char len[2] = {static_cast<char>(hl & 0xff), static_cast<char>(hl >> 8)};
  s.write(len, 2);
  s.write(header.data(), static_cast<std::streamsize>(header.size()));
}

void write_npy_sidecar(const std::filesystem::path& file, const core::HeightGrid& g, const std::string& values) {
  std::filesystem::path side = file;
  side += ".json";
  core::write_file_atomic(side, fmt::format("{{\"x0_mm\": {}, \"y0_mm\": {}, \"dx_mm\": {}, \"dy_mm\": {}, "
                                            "\"nx\": {}, \"ny\": {}, {}, \"row\": \"y\"}}\n",
                                            g.x0_mm, g.y0_mm, g.dx_mm, g.dy_mm, g.nx(), g.ny(), values));
}

}  // namespace

void write_height_npy(const std::filesystem::path& file, const core::HeightGrid& g) {
  core::AtomicFile out(file);
  write_npy_header(out.stream(), "<f8", g.ny(), g.nx());
  out.stream().write(reinterpret_cast<const char*>(g.z_mm.data()),
                     static_cast<std::streamsize>(g.z_mm.size() * sizeof(double)));
  out.commit();
  write_npy_sidecar(file, g, "\"z_unit\": \"mm\"");
}

void write_index_npy(const std::filesystem::path& file, const IndexGrid& index, const core::HeightGrid& on,
                     const std::string& meaning) {
  if (index.rows() != on.ny() || index.cols() != on.nx())
    throw core::Error(fmt::format("{}: the index is {} x {} nodes, its grid {} x {}", file.string(), index.cols(),
                                  index.rows(), on.nx(), on.ny()));
  core::AtomicFile out(file);
  write_npy_header(out.stream(), "|i1", index.rows(), index.cols());
  out.stream().write(reinterpret_cast<const char*>(index.data()), static_cast<std::streamsize>(index.size()));
  out.commit();
  std::string quoted;  // `meaning` as a JSON string (it is ours: no control characters)
  for (const char c : meaning) quoted += (c == '"' || c == '\\') ? std::string("\\") + c : std::string(1, c);
  write_npy_sidecar(file, on, "\"values\": \"" + quoted + "\"");
}

IndexGrid read_index_npy(const std::filesystem::path& file) {
  const std::string what = file.string();
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(what + ": cannot open the file");
  char magic[8];
  if (!in.read(magic, 8) || std::memcmp(magic, "\x93NUMPY", 6) != 0)
    throw core::Error(what + ": not a NumPy .npy file (expected the magic \\x93NUMPY)");
  const int major = static_cast<unsigned char>(magic[6]);
  if (major < 1 || major > 3) throw core::Error(fmt::format("{}: NPY version {} (expected 1.0 to 3.0)", what, major));
  unsigned char len[4] = {0, 0, 0, 0};
  if (!in.read(reinterpret_cast<char*>(len), major == 1 ? 2 : 4)) throw core::Error(what + ": cut short in its header");
  const std::size_t hl = len[0] | (len[1] << 8) | (static_cast<std::size_t>(len[2]) << 16) |
                         (static_cast<std::size_t>(len[3]) << 24);
  if (hl > 65536) throw core::Error(fmt::format("{}: a header of {} bytes (expected under 64 KiB)", what, hl));
  std::string header(hl, '\0');
  if (!in.read(header.data(), static_cast<std::streamsize>(hl))) throw core::Error(what + ": cut short in its header");
  // The dict's three keys, as numpy.save writes them ('descr': '|i1', 'fortran_order': False, 'shape': (ny, nx)).
  auto value_of = [&](const std::string& key) {
    const std::size_t k = header.find("'" + key + "'");
    if (k == std::string::npos) throw core::Error(what + ": its header has no '" + key + "'");
    std::size_t v = header.find(':', k);
    if (v == std::string::npos) throw core::Error(what + ": its header's '" + key + "' has no value");
    ++v;
    while (v < header.size() && header[v] == ' ') ++v;
    return v;
  };
  std::size_t d = value_of("descr");
  const std::size_t d_end = header.find('\'', d + 1);
  const std::string descr = d < header.size() && header[d] == '\'' && d_end != std::string::npos
                                ? header.substr(d + 1, d_end - d - 1)
                                : std::string();
  const bool is_unsigned = descr == "|u1" || descr == "u1";
  if (descr != "|i1" && descr != "i1" && !is_unsigned)
    throw core::Error(what + ": values of type '" + descr + "' (expected 8-bit integers, '|i1')");
  const bool fortran = header.compare(value_of("fortran_order"), 4, "True") == 0;
  const std::size_t sh = value_of("shape");
  long long ny = -1, nx = -1;
  char close = 0;
  if (std::sscanf(header.c_str() + sh, "(%lld, %lld%c", &ny, &nx, &close) != 3 || (close != ')' && close != ','))
    throw core::Error(what + ": its shape is not 2-D (expected (ny, nx))");
  if (ny < 1 || nx < 1 || ny > kMaxNodes / nx)
    throw core::Error(fmt::format("{}: a shape of {} x {} nodes (expected 1 to {} nodes)", what, ny, nx, kMaxNodes));
  IndexGrid g(ny, nx);
  std::vector<std::int8_t> raw(static_cast<std::size_t>(ny * nx));
  if (!in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(raw.size())))
    throw core::Error(fmt::format("{}: cut short: {} x {} values expected", what, ny, nx));
  for (long long j = 0; j < ny; ++j)
    for (long long i = 0; i < nx; ++i) {
      const std::int8_t v = raw[static_cast<std::size_t>(fortran ? i * ny + j : j * nx + i)];
      if (is_unsigned && v < 0)
        throw core::Error(fmt::format("{}: value {} at row {}, column {} (expected at most 127)", what,
                                      static_cast<unsigned char>(v), j, i));
      g(j, i) = v;
    }
  return g;
}

// ---- points on a lattice ----

namespace {

// The lattice of one coordinate: origin and step from the distinct values (gaps that are multiples of the step
// are missing columns), or an error.
struct Lattice {
  double origin = 0, step = 1;
  long long count = 1;
};

Lattice lattice_of(std::vector<double> v, const std::string& what, const char* axis) {
  std::sort(v.begin(), v.end());
  const double lo = v.front(), hi = v.back(), range = hi - lo;
  Lattice L;
  L.origin = lo;
  if (!(range > 0)) return L;
  const double tol = 1e-9 * std::max(range, std::max(std::abs(lo), std::abs(hi)));
  double gap = HUGE_VAL;
  for (std::size_t k = 1; k < v.size(); ++k)
    if (v[k] - v[k - 1] > tol) gap = std::min(gap, v[k] - v[k - 1]);
  const double n = std::round(range / gap);
  if (!(n >= 1) || n > static_cast<double>(kMaxNodes))
    throw core::Error(what +
                      fmt::format(": the {} coordinates do not form a grid (range {:.9g} mm, smallest step {:.9g} mm)",
                                  axis, range, gap));
  L.step = range / n;
  L.count = static_cast<long long>(n) + 1;
  for (double x : v) {
    const double k = std::round((x - lo) / L.step);
    if (std::abs(x - (lo + k * L.step)) > 1e-3 * L.step)
      throw core::Error(what +
                        fmt::format(": {} = {:.9g} mm is not on the grid of step {:.9g} mm from {:.9g} mm; the points "
                                    "must lie on a regular x/y grid",
                                    axis, x, L.step, lo));
  }
  return L;
}

}  // namespace

core::HeightGrid points_to_grid(const Eigen::Matrix<double, Eigen::Dynamic, 3>& p, const std::string& what) {
  const Eigen::Index n = p.rows();
  if (n == 0) throw core::Error(what + ": no points");
  std::vector<double> xs(static_cast<std::size_t>(n)), ys(static_cast<std::size_t>(n));
  for (Eigen::Index k = 0; k < n; ++k) {
    if (!std::isfinite(p(k, 0)) || !std::isfinite(p(k, 1)))
      throw core::Error(what + fmt::format(": point {} has no finite x and y", k + 1));
    xs[static_cast<std::size_t>(k)] = p(k, 0), ys[static_cast<std::size_t>(k)] = p(k, 1);
  }
  Lattice lx = lattice_of(xs, what, "x"), ly = lattice_of(ys, what, "y");
  // A single row or column: take the other axis' step, so the grid is square.
  if (lx.count == 1 && ly.count > 1) lx.step = ly.step;
  if (ly.count == 1 && lx.count > 1) ly.step = lx.step;
  const double nodes = static_cast<double>(lx.count) * static_cast<double>(ly.count);
  if (nodes > static_cast<double>(kMaxNodes) || nodes > 16.0 * static_cast<double>(n) + 1024)
    throw core::Error(what + fmt::format(": {} points would need a {} x {} grid; they are too sparse to be one", n,
                                         lx.count, ly.count));
  core::HeightGrid g;
  g.x0_mm = lx.origin, g.y0_mm = ly.origin, g.dx_mm = lx.step, g.dy_mm = ly.step;
  g.z_mm = core::HeightArray::Constant(static_cast<Eigen::Index>(ly.count), static_cast<Eigen::Index>(lx.count), kNaN);
  std::vector<std::uint8_t> taken(static_cast<std::size_t>(nodes), 0);
  for (Eigen::Index k = 0; k < n; ++k) {
    const auto i = static_cast<Eigen::Index>(std::llround((p(k, 0) - lx.origin) / lx.step));
    const auto j = static_cast<Eigen::Index>(std::llround((p(k, 1) - ly.origin) / ly.step));
    const std::size_t c = static_cast<std::size_t>(j * g.nx() + i);
    if (taken[c])
      throw core::Error(what +
                        fmt::format(": two points at x {:.9g}, y {:.9g} mm (point {})", p(k, 0), p(k, 1), k + 1));
    taken[c] = 1;
    g.z_mm(j, i) = std::isfinite(p(k, 2)) ? p(k, 2) : kNaN;
  }
  return g;
}

core::HeightGrid read_xyz_grid(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  return read_xyz_grid(in, file.string());
}

core::HeightGrid read_xyz_grid(std::istream& in, const std::string& file_name) {
  const std::filesystem::path file(file_name);
  int pow10 = -3;
  std::vector<double> v;
  std::string line;
  std::vector<std::string_view> f;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim_blanks(line);
    if (t.empty()) continue;
    if (t[0] == '#' || t.rfind("//", 0) == 0) {
      const std::string l = lower(t);
      for (const char* key : {"unit:", "units:", "unit =", "units ="}) {
        const auto at = l.find(key);
        if (at == std::string::npos) continue;
        const std::string u = trim_blanks(t.substr(at + std::strlen(key)));
        const auto p = length_unit_pow10(u);
        if (!p)
          throw core::Error(
              core::located(file.string(), lineno, "unknown length unit \"" + u.substr(0, 20) + "\" (m, mm, um, nm)"));
        pow10 = *p;
      }
      continue;
    }
    split_fields(t, f);
    if (f.size() != 3) {
      // A header line of words before the data ("x y z", "X[mm] Y[mm] Z[mm]").
      if (v.empty() && !f.empty() && !std::isdigit(static_cast<unsigned char>(f[0][0])) && f[0][0] != '-' &&
          f[0][0] != '+' && f[0][0] != '.')
        continue;
      throw core::Error(
          core::located(file.string(), lineno, fmt::format("expected 3 values x y z, found {}", f.size())));
    }
    for (int c = 0; c < 3; ++c) {
      const auto x = value_mm(f[static_cast<std::size_t>(c)], pow10);
      if (!x || (c < 2 && !std::isfinite(*x))) {
        if (v.empty() && c == 0) goto next_line;  // a header of words
        throw core::Error(
            core::located(file.string(), lineno,
                          "not a number: \"" + std::string(f[static_cast<std::size_t>(c)]).substr(0, 40) + "\""));
      }
      v.push_back(*x);
    }
  next_line:;
  }
  if (v.empty()) throw core::Error(file.string() + ": no points (expected lines of x y z)");
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> pts(
      v.data(), static_cast<Eigen::Index>(v.size() / 3), 3);
  return points_to_grid(pts, file.string());
}

void write_xyz(const std::filesystem::path& file, const core::HeightGrid& g) {
  core::AtomicFile out(file);
  auto& s = out.stream();
  std::string line;
  for (Eigen::Index j = 0; j < g.ny(); ++j) {
    line.clear();
    for (Eigen::Index i = 0; i < g.nx(); ++i)
      if (g.valid(j, i)) line += fmt::format("{} {} {}\n", g.x(i), g.y(j), g.z_mm(j, i));
    s << line;
  }
  out.commit();
}

core::HeightGrid read_matrix_grid(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  return read_matrix_grid(in, file.string());
}

namespace {

// "key: value" or "key = value" pairs of a header line; several "k=v" pairs may share a line ("h=305 w=75"): the
// value of each runs to the last blank before the next key.
std::vector<std::pair<std::string, std::string>> header_pairs(const std::string& body) {
  std::vector<std::pair<std::string, std::string>> out;
  const std::size_t colon = body.find(':'), eq = body.find('=');
  if (colon != std::string::npos && (eq == std::string::npos || colon < eq)) {
    out.emplace_back(lower(trim_blanks(std::string_view(body).substr(0, colon))),
                     trim_blanks(std::string_view(body).substr(colon + 1)));
    return out;
  }
  std::vector<std::size_t> eqs;
  for (std::size_t k = 0; k < body.size(); ++k)
    if (body[k] == '=') eqs.push_back(k);
  if (eqs.empty()) return out;
  std::size_t key_start = 0;
  for (std::size_t e = 0; e < eqs.size(); ++e) {
    const std::string key = lower(trim_blanks(std::string_view(body).substr(key_start, eqs[e] - key_start)));
    std::size_t value_end = body.size(), next_key = body.size();
    if (e + 1 < eqs.size()) {
      const std::string_view seg = std::string_view(body).substr(eqs[e] + 1, eqs[e + 1] - eqs[e] - 1);
      const std::string t = trim_blanks(seg);
      const std::size_t sp = seg.find_last_of(" \t", seg.find_last_not_of(" \t"));
      if (sp == std::string_view::npos || t.empty()) {
        value_end = next_key = eqs[e + 1];  // "a=b=c": not pairs we know
      } else {
        value_end = eqs[e] + 1 + sp;
        next_key = value_end;
      }
    }
    out.emplace_back(key, trim_blanks(std::string_view(body).substr(eqs[e] + 1, value_end - eqs[e] - 1)));
    key_start = next_key;
  }
  return out;
}

}  // namespace

core::HeightGrid read_matrix_grid(std::istream& in, const std::string& file_name) {
  const std::filesystem::path file(file_name);
  std::optional<double> width, height, dx, dy, x0, y0, pixel, zfactor;
  std::optional<long long> rows_declared, cols_declared;
  std::string zunit_name, data_unit;  // the unit the heights are in, as named
  int zpow10 = -3;
  bool zunit_is_length = true;
  std::optional<int> xunit, yunit;  // SPIP's x-unit / y-unit for x-length / y-length given without a unit
  std::vector<double> v;
  long long nx = -1;
  long long ny = 0;
  std::string line;
  std::vector<std::string_view> f;
  int lineno = 0;
  // "12.5 um" -> mm (a bare number takes `fallback` as its unit's power of ten)
  const auto length = [&](const std::string& val, int fallback = -3) -> double {
    std::vector<std::string_view> parts;
    split_fields(val, parts);
    if (parts.empty() || parts.size() > 2)
      throw core::Error(core::located(file.string(), lineno,
                                      "expected a length \"<number> <unit>\", found \"" + val.substr(0, 40) + "\""));
    int p = fallback;
    if (parts.size() == 2) {
      const auto u = length_unit_pow10(parts[1]);
      if (!u)
        throw core::Error(
            core::located(file.string(), lineno,
                          "unknown length unit \"" + std::string(parts[1]).substr(0, 20) + "\" (m, mm, um, nm)"));
      p = *u;
    }
    const auto x = parse_decimal_scaled(parts[0], p + 3);
    if (!x || !std::isfinite(*x))
      throw core::Error(
          core::located(file.string(), lineno, "not a number: \"" + std::string(parts[0]).substr(0, 40) + "\""));
    return *x;
  };
  const auto count = [&](const std::string& val) -> long long {
    const auto x = parse_decimal_scaled(val);
    if (!x || !(*x >= 1) || *x != std::floor(*x) || *x > static_cast<double>(kMaxNodes))
      throw core::Error(
          core::located(file.string(), lineno, "expected a count of points, found \"" + val.substr(0, 40) + "\""));
    return static_cast<long long>(*x);
  };
  const auto set_zunit = [&](const std::string& val) {
    zunit_name = val;
    const auto u = length_unit_pow10(val);
    zunit_is_length = static_cast<bool>(u);
    if (u) zpow10 = *u;
  };
  const auto header_line = [&](const std::string& body) {
    for (const auto& [key, val] : header_pairs(body)) {
      if (key == "width")
        width = length(val);
      else if (key == "height")
        height = length(val);
      else if (key == "x-length")
        width = length(val, xunit.value_or(-3));
      else if (key == "y-length")
        height = length(val, yunit.value_or(-3));
      else if (key == "dx" || key == "x spacing")
        dx = length(val);
      else if (key == "dy" || key == "y spacing")
        dy = length(val);
      else if (key == "pixel size")
        pixel = length(val);
      else if (key == "x0" || key == "x offset")
        x0 = length(val);
      else if (key == "y0" || key == "y offset")
        y0 = length(val);
      else if (key == "x-unit" || key == "y-unit") {
        const auto u = length_unit_pow10(val);
        if (!u)
          throw core::Error(core::located(file.string(), lineno,
                                          "unknown length unit \"" + val.substr(0, 20) + "\" (m, mm, um, nm)"));
        (key == "x-unit" ? xunit : yunit) = *u;
      } else if (key == "value units" || key == "z unit" || key == "z units" || key == "z-unit")
        set_zunit(val);
      else if (key == "data unit")
        data_unit = val;
      else if (key == "h")
        rows_declared = count(val);
      else if (key == "w")
        cols_declared = count(val);
      else if (key.rfind("height conversion factor", 0) == 0) {
        // "height conversion factor (-> m)=2.9e-8": heights times the factor are in the unit named in the key.
        const std::size_t arrow = key.find("->"), close = key.find(')', arrow == std::string::npos ? 0 : arrow);
        const std::string u = arrow == std::string::npos
                                  ? std::string()
                                  : trim_blanks(std::string_view(key).substr(
                                        arrow + 2, close == std::string::npos ? std::string::npos : close - arrow - 2));
        const auto p = length_unit_pow10(u);
        if (!p)
          throw core::Error(core::located(
              file.string(), lineno, "height conversion factor: the key names no length unit (\"-> m\" expected)"));
        const auto x = parse_decimal_scaled(val);
        if (!x || !std::isfinite(*x) || *x == 0)
          throw core::Error(
              core::located(file.string(), lineno,
                            "height conversion factor: \"" + val.substr(0, 40) + "\" is not a non-zero number"));
        zfactor = *x;
        zpow10 = *p;
        zunit_is_length = true;
      }
    }
  };
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim_blanks(line);
    if (t.empty()) continue;
    if (t[0] == '#') {
      header_line(trim_blanks(std::string_view(t).substr(1)));
      continue;
    }
    split_fields(t, f);
    // Before the first row of heights, a line that is not all numbers is a header line ("h=305 w=75").
    if (nx < 0 && t.find_first_of("=:") != std::string::npos &&
        std::any_of(f.begin(), f.end(),
                    [](std::string_view tok) { return !is_nan_token(tok) && !parse_decimal_scaled(tok); })) {
      header_line(t);
      continue;
    }
    if (nx < 0) {
      // The header is over: the heights' unit and factor are known.
      nx = static_cast<long long>(f.size());
      if (!zfactor && (!zunit_is_length || (!data_unit.empty() && !length_unit_pow10(data_unit))))
        throw core::Error(
            core::located(file.string(), lineno,
                          "the heights are in \"" + (zunit_is_length ? data_unit : zunit_name) +
                              "\", not a length, and the header gives no \"height conversion factor (-> m)\""));
      if (zunit_name.empty() && !zfactor && !data_unit.empty()) zpow10 = *length_unit_pow10(data_unit);
    }
    if (static_cast<long long>(f.size()) != nx)
      throw core::Error(
          core::located(file.string(), lineno, fmt::format("{} values, the first row has {}", f.size(), nx)));
    // Without a factor the decimal exponent shift is exact (units.hpp); a factor applies in double arithmetic.
    const double scale = zfactor ? *zfactor * std::pow(10.0, zpow10 + 3) : 1.0;
    for (const auto& tok : f) {
      const auto z = zfactor ? value_mm(tok, -3) : value_mm(tok, zpow10);
      if (!z)
        throw core::Error(
            core::located(file.string(), lineno, "not a number: \"" + std::string(tok).substr(0, 40) + "\""));
      v.push_back(std::isfinite(*z) ? *z * scale : kNaN);
    }
    ++ny;
    if (nx * ny > kMaxNodes) throw core::Error(core::located(file.string(), lineno, "more heights than vmsim accepts"));
  }
  if (nx <= 0 || ny == 0) throw core::Error(file.string() + ": no rows of heights");
  if (rows_declared && *rows_declared != ny)
    throw core::Error(file.string() +
                      fmt::format(": the header declares h={} rows, the file has {}", *rows_declared, ny));
  if (cols_declared && *cols_declared != nx)
    throw core::Error(file.string() +
                      fmt::format(": the header declares w={} columns, the rows have {} values", *cols_declared, nx));
  core::HeightGrid g;
  if (dx)
    g.dx_mm = *dx;
  else if (pixel)
    g.dx_mm = *pixel;
  else if (width)
    g.dx_mm = *width / static_cast<double>(nx);
  else
    throw core::Error(
        file.string() +
        ": the header gives no x spacing (\"# dx: 5 um\", \"pixel size=0.37 um\" or Gwyddion's \"# Width: 1 mm\")");
  if (dy)
    g.dy_mm = *dy;
  else if (pixel)
    g.dy_mm = *pixel;
  else if (height)
    g.dy_mm = *height / static_cast<double>(ny);
  else if (dx && !width)
    g.dy_mm = g.dx_mm;
  else
    throw core::Error(file.string() +
                      ": the header gives no y spacing (\"# dy: 5 um\" or Gwyddion's \"# Height: 1 mm\")");
  if (!(g.dx_mm > 0) || !(g.dy_mm > 0)) throw core::Error(file.string() + ": the grid spacing must be positive");
  g.x0_mm = x0.value_or(0.0);
  g.y0_mm = y0.value_or(0.0);
  g.z_mm = Eigen::Map<core::HeightArray>(v.data(), static_cast<Eigen::Index>(ny), static_cast<Eigen::Index>(nx));
  return g;
}

}  // namespace vmsim::metrology
