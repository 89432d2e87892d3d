#include "core/stl.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <string_view>
#include <system_error>
#include <tuple>
#include <unordered_map>
#include <vector>

namespace vmsim::core {

namespace {

namespace fs = std::filesystem;

// Coordinates beyond this are refused: no machine has a kilometre of travel, and keeping numbers far from the
// float range lets the binary writer and the float-based ray caster use them without overflow.
constexpr double kMaxCoordMm = 1e9;

// ---- reading the file ----

std::string read_whole_file(const fs::path& path) {
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (ec || !fs::exists(status)) throw Error(located(path.string(), 0, "cannot open the STL file: it does not exist"));
  // Devices and FIFOs (/dev/zero, a pipe) would be read forever: only regular files are STL files.
  if (!fs::is_regular_file(status)) throw Error(located(path.string(), 0, "not a regular file"));
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw Error(located(path.string(), 0, "cannot read the file size: " + ec.message()));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(located(path.string(), 0, std::string("cannot open: ") + std::strerror(errno)));
  std::string data(static_cast<std::size_t>(size), '\0');
  in.read(data.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size)
    throw Error(located(path.string(), 0, "the file changed size while it was read"));
  return data;
}

std::uint32_t le32(const char* p) {
  const auto* u = reinterpret_cast<const unsigned char*>(p);
  return static_cast<std::uint32_t>(u[0]) | (static_cast<std::uint32_t>(u[1]) << 8) |
         (static_cast<std::uint32_t>(u[2]) << 16) | (static_cast<std::uint32_t>(u[3]) << 24);
}

float lefloat(const char* p) { return std::bit_cast<float>(le32(p)); }

bool is_text_byte(unsigned char c) { return !(c < 0x09 || (c > 0x0d && c < 0x20) || c == 0x7f); }

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
  return true;
}

// Where the ASCII text starts: after a UTF-8 byte-order mark and leading white space.
std::size_t text_start(const std::string& d) {
  std::size_t p = d.size() >= 3 && d.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
  while (p < d.size() && std::isspace(static_cast<unsigned char>(d[p]))) ++p;
  return p;
}

bool starts_with_solid(const std::string& d) {
  const std::size_t p = text_start(d);
  return d.size() >= p + 5 && iequals(std::string_view(d).substr(p, 5), "solid") &&
         (d.size() == p + 5 || std::isspace(static_cast<unsigned char>(d[p + 5])));
}

// A token for messages: at most 40 characters, control bytes shown as '?'.
std::string shown(std::string_view t) {
  std::string s(t.substr(0, 40));
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) == 0x7f) c = '?';
  if (t.size() > 40) s += "...";
  return s;
}

// ---- welding ----

class Welder {
 public:
  Welder(double tol, std::size_t expected_vertices) : tol_(tol) {
    if (tol_ == 0) exact_.reserve(expected_vertices);
  }

  int add(double x, double y, double z) {
    // -0 and +0 are the same point.
    x += 0.0, y += 0.0, z += 0.0;
    if (tol_ == 0) {
      const Key k{std::bit_cast<std::uint64_t>(x), std::bit_cast<std::uint64_t>(y), std::bit_cast<std::uint64_t>(z)};
      auto [it, inserted] = exact_.try_emplace(k, static_cast<int>(count()));
      if (inserted) push(x, y, z);
      return it->second;
    }
    const std::array<std::int64_t, 3> c{cell(x), cell(y), cell(z)};
    int best = -1;
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(Key{static_cast<std::uint64_t>(c[0] + dx), static_cast<std::uint64_t>(c[1] + dy),
                                    static_cast<std::uint64_t>(c[2] + dz)});
          if (it == cells_.end()) continue;
          for (int v : it->second) {
            const double ex = xyz_[3 * v] - x, ey = xyz_[3 * v + 1] - y, ez = xyz_[3 * v + 2] - z;
            // The earliest vertex in reach, whatever the order the cells were visited in (deterministic).
            if (ex * ex + ey * ey + ez * ez <= tol_ * tol_ && (best < 0 || v < best)) best = v;
          }
        }
    if (best >= 0) return best;
    const int id = static_cast<int>(count());
    cells_[Key{static_cast<std::uint64_t>(c[0]), static_cast<std::uint64_t>(c[1]), static_cast<std::uint64_t>(c[2])}]
        .push_back(id);
    push(x, y, z);
    return id;
  }

  std::size_t count() const { return xyz_.size() / 3; }
  const std::vector<double>& xyz() const { return xyz_; }

 private:
  struct Key {
    std::uint64_t a, b, c;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = k.a * 0x9E3779B97F4A7C15ULL;
      h ^= (k.b + 0x632BE59BD9B4E019ULL + (h << 6) + (h >> 2));
      h ^= (k.c + 0x85EBCA77C2B2AE63ULL + (h << 6) + (h >> 2));
      return static_cast<std::size_t>(h ^ (h >> 29));
    }
  };
  // |x| <= 1e9 and tol >= 1e-9 (checked by the caller): the cell index stays far inside int64.
  std::int64_t cell(double x) const { return static_cast<std::int64_t>(std::floor(x / tol_)); }
  void push(double x, double y, double z) {
    xyz_.push_back(x);
    xyz_.push_back(y);
    xyz_.push_back(z);
  }
  double tol_;
  std::unordered_map<Key, int, KeyHash> exact_;
  std::unordered_map<Key, std::vector<int>, KeyHash> cells_;
  std::vector<double> xyz_;
};

TriangleMesh make_mesh(const Welder& w, std::vector<int>& tri) {
  TriangleMesh m;
  const auto nv = static_cast<Eigen::Index>(w.count());
  m.vertices_mm.resize(nv, 3);
  std::copy(w.xyz().begin(), w.xyz().end(), m.vertices_mm.data());
  m.triangles.resize(static_cast<Eigen::Index>(tri.size() / 3), 3);
  std::copy(tri.begin(), tri.end(), m.triangles.data());
  return m;
}

// ---- binary ----

TriangleMesh read_binary(const std::string& file, const std::string& d, std::uint32_t n, double tol) {
  // The caller has checked d.size() == 84 + 50 n: nothing below allocates more than the file justifies.
  if (static_cast<std::uint64_t>(n) * 3 > static_cast<std::uint64_t>(std::numeric_limits<int>::max()))
    throw Error(located(file, 0, fmt::format("{} triangles are more than vmsim can index", n)));
  Welder w(tol, tol == 0 ? static_cast<std::size_t>(n) / 2 + 4 : 0);
  std::vector<int> tri;
  tri.reserve(static_cast<std::size_t>(n) * 3);
  for (std::uint32_t k = 0; k < n; ++k) {
    const std::size_t rec = 84 + 50 * static_cast<std::size_t>(k);
    for (int v = 0; v < 3; ++v) {
      double c[3];
      for (int a = 0; a < 3; ++a) {
        c[a] = lefloat(d.data() + rec + 12 + 12 * v + 4 * a);
        if (!std::isfinite(c[a]) || std::abs(c[a]) > kMaxCoordMm)
          throw Error(located(file, 0,
                              fmt::format("triangle #{} (byte {}): vertex {} has coordinate {} = {}; expected a "
                                          "finite number within +-1e9 mm",
                                          k + 1, rec + 12 + 12 * v + 4 * a, v + 1, "xyz"[a], c[a])));
      }
      tri.push_back(w.add(c[0], c[1], c[2]));
    }
  }
  return make_mesh(w, tri);
}

// ---- ASCII ----

class AsciiParser {
 public:
  AsciiParser(const std::string& file, const std::string& d, double tol) : file_(file), d_(d), w_(tol, 0) {}

  TriangleMesh parse() {
    pos_ = text_start(d_);
    count_lines_to(pos_);
    expect("solid");
    skip_line();  // the solid's name
    for (;;) {
      std::string_view t = next();
      if (t.empty()) fail(line_, "the file ends without \"endsolid\" (truncated?)");
      if (iequals(t, "endsolid")) {
        skip_line();
        t = next();
        if (t.empty()) break;
        // Some exporters write one solid per body into the same file.
        if (iequals(t, "solid")) {
          skip_line();
          continue;
        }
        fail(tok_line_,
             "expected the end of the file or another \"solid\" after \"endsolid\", found \"" + shown(t) + "\"");
      }
      if (!iequals(t, "facet")) fail(tok_line_, "expected \"facet\" or \"endsolid\", found \"" + shown(t) + "\"");
      expect("normal");
      for (int a = 0; a < 3; ++a) (void)number(false);  // normals are ignored, but must be numbers
      expect("outer");
      expect("loop");
      for (int v = 0; v < 3; ++v) {
        std::string_view k = next();
        if (!iequals(k, "vertex"))
          fail(tok_line_, fmt::format("expected \"vertex\" (vertex {} of 3), found \"{}\"", v + 1,
                                      k.empty() ? std::string("end of file") : shown(k)));
        double c[3];
        for (int a = 0; a < 3; ++a) c[a] = number(true);
        tri_.push_back(w_.add(c[0], c[1], c[2]));
        if (tri_.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
          fail(tok_line_, "too many triangles for vmsim to index");
      }
      std::string_view e = next();
      if (iequals(e, "vertex")) fail(tok_line_, "a facet with more than three vertices (STL facets are triangles)");
      if (!iequals(e, "endloop"))
        fail(tok_line_, "expected \"endloop\", found \"" + (e.empty() ? std::string("end of file") : shown(e)) + "\"");
      expect("endfacet");
    }
    return make_mesh(w_, tri_);
  }

 private:
  [[noreturn]] void fail(int line, const std::string& msg) const { throw Error(located(file_, line, msg)); }

  void count_lines_to(std::size_t p) {
    for (std::size_t i = 0; i < p; ++i)
      if (d_[i] == '\n') ++line_;
  }

  // The next white-space-separated token ("" at the end of the file); tok_line_ is its line.
  std::string_view next() {
    while (pos_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[pos_]))) {
      if (d_[pos_] == '\n') ++line_;
      ++pos_;
    }
    const std::size_t b = pos_;
    while (pos_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
    tok_line_ = line_;
    return std::string_view(d_).substr(b, pos_ - b);
  }

  void skip_line() {
    while (pos_ < d_.size() && d_[pos_] != '\n') ++pos_;
  }

  void expect(std::string_view kw) {
    const std::string_view t = next();
    if (!iequals(t, kw))
      fail(tok_line_,
           fmt::format("expected \"{}\", found \"{}\"", kw, t.empty() ? std::string("end of file") : shown(t)));
  }

  double number(bool coordinate) {
    std::string_view t = next();
    if (t.empty()) fail(tok_line_, "expected a number, found the end of the file");
    std::string_view s = t;
    if (s.size() > 1 && s[0] == '+') s.remove_prefix(1);  // from_chars refuses a leading '+'
    double v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec == std::errc::result_out_of_range) fail(tok_line_, "number \"" + shown(t) + "\" is out of range");
    if (ec != std::errc() || p != s.data() + s.size()) fail(tok_line_, "expected a number, found \"" + shown(t) + "\"");
    if (coordinate && (!std::isfinite(v) || std::abs(v) > kMaxCoordMm))
      fail(tok_line_, "vertex coordinate \"" + shown(t) + "\" is not a finite number within +-1e9 mm");
    return v;
  }

  const std::string& file_;
  const std::string& d_;
  Welder w_;
  std::vector<int> tri_;
  std::size_t pos_ = 0;
  int line_ = 1, tok_line_ = 1;
};

// ---- writing ----

void check_writable(const fs::path& path, const TriangleMesh& mesh) {
  const auto nv = mesh.vertices_mm.rows();
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c)
      if (mesh.triangles(t, c) < 0 || mesh.triangles(t, c) >= nv)
        throw Error(located(
            path.string(), 0,
            fmt::format("cannot write triangle #{}: vertex index {} out of range", t + 1, mesh.triangles(t, c))));
  for (Eigen::Index v = 0; v < nv; ++v)
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(mesh.vertices_mm(v, a)) || std::abs(mesh.vertices_mm(v, a)) > kMaxCoordMm)
        throw Error(located(path.string(), 0,
                            fmt::format("cannot write vertex #{}: coordinate {} is not within +-1e9 mm", v + 1,
                                        mesh.vertices_mm(v, a))));
}

Eigen::Vector3d unit_normal(const TriangleMesh& m, Eigen::Index t) {
  const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(t, 0)).transpose();
  const Eigen::Vector3d b = m.vertices_mm.row(m.triangles(t, 1)).transpose();
  const Eigen::Vector3d c = m.vertices_mm.row(m.triangles(t, 2)).transpose();
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double l = n.norm();
  return l > 0 ? Eigen::Vector3d(n / l) : Eigen::Vector3d::Zero();
}

std::string shortest(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string point(const TriangleMesh& m, int v) {
  return fmt::format("({}, {}, {})", m.vertices_mm(v, 0), m.vertices_mm(v, 1), m.vertices_mm(v, 2));
}

}  // namespace

TriangleMesh read_stl(const fs::path& path, const StlReadOptions& options) {
  const std::string file = path.string();
  const double tol = options.weld_tolerance_mm;
  if (!(tol == 0 || (tol >= 1e-9 && tol <= 10)))
    throw Error(located(file, 0, fmt::format("weld tolerance {} mm: expected 0 (exact) or 1e-9 to 10 mm", tol)));
  const std::string d = read_whole_file(path);
  const bool solid = starts_with_solid(d);
  if (d.size() >= 84) {
    const std::uint32_t n = le32(d.data() + 80);
    const std::uint64_t expected = 84 + 50 * static_cast<std::uint64_t>(n);
    if (expected == d.size()) {
      // A binary file whose header happens to start with "solid" still holds float bytes that are not text.
      const bool all_text =
          std::all_of(d.begin() + 80, d.end(), [](char c) { return is_text_byte(static_cast<unsigned char>(c)); });
      if (!(solid && all_text)) return read_binary(file, d, n, tol);
    }
    if (!solid)
      throw Error(located(file, 0,
                          fmt::format("not an STL file: it does not start with \"solid\" (ASCII STL), and as a binary "
                                      "STL its header declares {} triangles, which take 84 + 50 x {} = {} bytes, but "
                                      "the file has {} bytes (truncated, or not an STL file)",
                                      n, n, expected, d.size())));
  } else if (!solid) {
    throw Error(located(file, 0,
                        fmt::format("not an STL file: {} bytes, too short for a binary STL (84-byte header) and it "
                                    "does not start with \"solid\" (ASCII STL)",
                                    d.size())));
  }
  // ASCII. A stray binary byte means a binary file with a "solid" header whose size does not match, or a damaged
  // text file: say both.
  const auto bad =
      std::find_if(d.begin(), d.end(), [](char c) { return !is_text_byte(static_cast<unsigned char>(c)); });
  if (bad != d.end()) {
    const auto at = static_cast<std::size_t>(bad - d.begin());
    const int line = 1 + static_cast<int>(std::count(d.begin(), bad, '\n'));
    std::string binary_reading = "too short for a binary STL";
    if (d.size() >= 84) {
      const std::uint32_t n = le32(d.data() + 80);
      binary_reading =
          fmt::format("as a binary STL its header declares {} triangles ({} bytes), but the file has {} bytes", n,
                      84 + 50 * static_cast<std::uint64_t>(n), d.size());
    }
    throw Error(located(file, line,
                        fmt::format("binary byte 0x{:02x} at byte {} in a file that starts with \"solid\": not an "
                                    "ASCII STL, and {}",
                                    static_cast<unsigned>(static_cast<unsigned char>(*bad)), at, binary_reading)));
  }
  return AsciiParser(file, d, tol).parse();
}

std::optional<std::string> closed_mesh_problem(const TriangleMesh& mesh) {
  const auto nv = mesh.vertices_mm.rows();
  const auto nt = mesh.triangles.rows();
  if (nt == 0) return "the mesh has no triangles";
  for (Eigen::Index t = 0; t < nt; ++t)
    for (int c = 0; c < 3; ++c)
      if (mesh.triangles(t, c) < 0 || mesh.triangles(t, c) >= nv)
        return fmt::format("facet #{} names vertex index {}, but the mesh has {} vertices", t + 1, mesh.triangles(t, c),
                           nv);
  for (Eigen::Index v = 0; v < nv; ++v)
    if (!mesh.vertices_mm.row(v).allFinite()) return fmt::format("vertex #{} is not finite", v + 1);

  struct Edge {
    int lo, hi, tri;
    bool forward;  // runs lo -> hi in its triangle
  };
  std::vector<Edge> edges;
  edges.reserve(static_cast<std::size_t>(nt) * 3);
  std::size_t degenerate = 0;
  Eigen::Index first_degenerate = -1;
  for (Eigen::Index t = 0; t < nt; ++t) {
    const int v[3] = {mesh.triangles(t, 0), mesh.triangles(t, 1), mesh.triangles(t, 2)};
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
      if (degenerate++ == 0) first_degenerate = t;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const int a = v[k], b = v[(k + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), static_cast<int>(t), a < b});
    }
  }
  if (edges.empty()) return fmt::format("all {} facets have a repeated vertex (no area)", nt);
  std::sort(edges.begin(), edges.end(),
            [](const Edge& x, const Edge& y) { return std::tie(x.lo, x.hi, x.tri) < std::tie(y.lo, y.hi, y.tri); });
  // Among the problem edges, report the one met first in file order (its lowest facet).
  const Edge* worst = nullptr;
  std::size_t worst_count = 0;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
    const std::size_t n = j - i;
    const bool problem = n != 2 || edges[i].forward == edges[i + 1].forward;
    if (problem && (!worst || edges[i].tri < worst->tri)) {
      worst = &edges[i];
      worst_count = n;
    }
    i = j;
  }
  if (!worst) return std::nullopt;
  const std::string segment = point(mesh, worst->lo) + " - " + point(mesh, worst->hi);
  const std::string edge = "the edge " + segment;
  std::string msg;
  if (worst_count == 1) {
    msg = fmt::format(
        "the mesh is not closed: {} belongs to facet #{} only (a hole, or a gap between facets whose "
        "corners do not coincide)",
        edge, worst->tri + 1);
  } else if (worst_count > 2) {
    std::string list;
    for (std::size_t k = 0; k < worst_count; ++k) list += (k ? ", #" : "#") + std::to_string(worst[k].tri + 1);
    msg = fmt::format("the mesh is not manifold: {} is shared by {} facets ({}); a closed surface has exactly 2", edge,
                      worst_count, list);
  } else {
    msg = fmt::format(
        "inconsistent orientation: facets #{} and #{} run along their shared edge {} in the same "
        "direction, so one of them is flipped (vertices go counter-clockwise seen from outside)",
        worst->tri + 1, worst[1].tri + 1, segment);
  }
  if (degenerate > 0)
    msg += fmt::format(
        " [the mesh also has {} facet(s) with a repeated vertex, e.g. #{}, which bound no area and were "
        "ignored]",
        degenerate, first_degenerate + 1);
  return msg;
}

void check_closed(const TriangleMesh& mesh, const std::string& file) {
  if (auto p = closed_mesh_problem(mesh)) throw Error(located(file, 0, *p));
}

void write_stl_binary(const fs::path& path, const TriangleMesh& mesh) {
  check_writable(path, mesh);
  const auto nt = mesh.triangles.rows();
  if (static_cast<std::uint64_t>(nt) > std::numeric_limits<std::uint32_t>::max())
    throw Error(located(path.string(), 0, "too many triangles for a binary STL (at most 2^32 - 1)"));
  // The whole file sized once and each 50-byte record stored in place (issue 21: a byte-by-byte push_back with its
  // capacity check was most of this function's time on a run's millions of triangles).
  std::string out(84 + 50 * static_cast<std::size_t>(nt), '\0');
  std::string header = "vmsim binary STL, units mm";
  header.resize(80, ' ');
  out.replace(0, 80, header);
  char* w = out.data() + 80;
  auto put = [&w](std::uint32_t v) {
    if constexpr (std::endian::native == std::endian::little) {
      std::memcpy(w, &v, 4);  // one store; the byte loop below is what other hosts need
      w += 4;
    } else {
      for (int k = 0; k < 4; ++k) *w++ = static_cast<char>((v >> (8 * k)) & 0xffu);
    }
  };
  put(static_cast<std::uint32_t>(nt));
  const double* xyz = mesh.vertices_mm.data();  // row-major: vertex v's x y z at 3 v
  for (Eigen::Index t = 0; t < nt; ++t) {
    const Eigen::Vector3d n = unit_normal(mesh, t);
    for (int a = 0; a < 3; ++a) put(std::bit_cast<std::uint32_t>(static_cast<float>(n[a])));
    for (int c = 0; c < 3; ++c) {
      const double* p = xyz + 3 * static_cast<std::ptrdiff_t>(mesh.triangles(t, c));
      for (int a = 0; a < 3; ++a) put(std::bit_cast<std::uint32_t>(static_cast<float>(p[a])));
    }
    w += 2;  // attribute byte count: zero
  }
  write_file_atomic(path, out);
}

void write_stl_ascii(const fs::path& path, const TriangleMesh& mesh, const std::string& solid_name) {
  check_writable(path, mesh);
  // The name runs to the end of the "solid" line: keep it on one line.
  std::string name = solid_name;
  for (char& c : name)
    if (c == '\n' || c == '\r') c = ' ';
  std::string out = "solid " + name + "\n";
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    const Eigen::Vector3d n = unit_normal(mesh, t);
    out += "  facet normal " + shortest(n.x()) + " " + shortest(n.y()) + " " + shortest(n.z()) + "\n    outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.triangles(t, c);
      out += "      vertex " + shortest(mesh.vertices_mm(v, 0)) + " " + shortest(mesh.vertices_mm(v, 1)) + " " +
             shortest(mesh.vertices_mm(v, 2)) + "\n";
    }
    out += "    endloop\n  endfacet\n";
  }
  out += "endsolid " + name + "\n";
  write_file_atomic(path, out);
}

}  // namespace vmsim::core
