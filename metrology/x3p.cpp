#include "metrology/x3p.hpp"
#include "metrology/reader_common.hpp"
#include "core/memory.hpp"
#include "core/regular_file.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>
#include <pugixml.hpp>
#include <zip.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

namespace vmsim::metrology {

namespace {

// Keeps a hostile file from making vmsim allocate without limit (the points: kMaxGridPoints): main.xml of 256 MiB
// holds ~10 M points as text (large scans come as binary data).
constexpr std::uint64_t kMaxXmlBytes = std::uint64_t{1} << 28;

// The vendor extension (ISO5436_2/VendorSpecificID) vmsim writes: for each point, how many ulps the mm height
// is from 1000 times the metre value in data.bin (int8, x fastest). See write_x3p.
constexpr const char* kVendorUri = "urn:vmsim:x3p:z-mm-ulp-correction:1";
constexpr const char* kVendorEntry = "vmsim/z_mm_ulp_correction.bin";

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw core::Error(file.string() + ": " + what);
}

// ---- zip entries, read from memory with limits ----

class ZipReader {
 public:
  ZipReader(const std::filesystem::path& file, const std::string& bytes) : file_(file) {
    zip_error_t ze;
    zip_error_init(&ze);
    zip_source_t* src = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &ze);
    if (!src) fail(file, std::string("not readable as a zip archive: ") + zip_error_strerror(&ze));
    za_ = zip_open_from_source(src, ZIP_RDONLY | ZIP_CHECKCONS, &ze);
    if (!za_) {
      zip_source_free(src);
      const std::string why = zip_error_strerror(&ze);
      zip_error_fini(&ze);
      fail(file, "not a valid zip archive (an X3P file is a zip of main.xml and bindata/): " + why);
    }
    zip_error_fini(&ze);
  }
  ~ZipReader() {
    if (za_) zip_discard(za_);
  }
  ZipReader(const ZipReader&) = delete;
  ZipReader& operator=(const ZipReader&) = delete;

  // An entry named relative to main.xml's folder (the archive's root in a standard file), or from the root.
  std::optional<zip_uint64_t> find(std::string name) const {
    while (name.rfind("./", 0) == 0) name.erase(0, 2);
    while (!name.empty() && name.front() == '/') name.erase(0, 1);
    if (!base_.empty()) {
      const zip_int64_t i = zip_name_locate(za_, (base_ + name).c_str(), ZIP_FL_NOCASE);
      if (i >= 0) return static_cast<zip_uint64_t>(i);
    }
    const zip_int64_t i = zip_name_locate(za_, name.c_str(), ZIP_FL_NOCASE);
    if (i < 0) return std::nullopt;
    return static_cast<zip_uint64_t>(i);
  }
  void set_base(const std::string& folder) { base_ = folder; }
  std::string name(zip_uint64_t index) const {
    const char* s = zip_get_name(za_, index, 0);
    return s ? std::string(s) : std::string();
  }

  std::vector<std::string> names() const {
    std::vector<std::string> out;
    const zip_int64_t n = zip_get_num_entries(za_, 0);
    for (zip_int64_t i = 0; i < n && i < 100000; ++i)
      if (const char* s = zip_get_name(za_, static_cast<zip_uint64_t>(i), 0)) out.emplace_back(s);
    return out;
  }

  // The entry's bytes. Its declared size must be at most max_bytes (and exactly `exact` when given); the bytes
  // actually inflated must match the declaration (libzip checks the CRC at the end).
  std::string read(zip_uint64_t index, const std::string& name, std::uint64_t max_bytes,
                   std::optional<std::uint64_t> exact = std::nullopt) const {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(za_, index, 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE))
      fail(file_, name + ": cannot read the zip entry's size: " + zip_strerror(za_));
    if (exact && st.size != *exact)
      fail(file_,
           fmt::format("{}: {} bytes, expected {} for the declared dimensions and data types", name, st.size, *exact));
    if (st.size > max_bytes)
      fail(file_, fmt::format("{}: {} bytes, more than the {} bytes vmsim accepts", name, st.size, max_bytes));
    zip_file_t* zf = zip_fopen_index(za_, index, 0);
    if (!zf) fail(file_, name + ": cannot open the zip entry: " + zip_strerror(za_));
    std::string out;
    // Grow with the data actually inflated, not with the size the (possibly lying) header declares.
    out.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(st.size, 1u << 26)));
    char buf[1 << 16];
    for (;;) {
      const zip_int64_t n = zip_fread(zf, buf, sizeof buf);
      if (n < 0) {
        const std::string why = zip_error_strerror(zip_file_get_error(zf));
        zip_fclose(zf);
        fail(file_, name + ": corrupt zip entry: " + why);
      }
      if (n == 0) break;
      if (out.size() + static_cast<std::uint64_t>(n) > st.size) {
        zip_fclose(zf);
        fail(file_, fmt::format("{}: inflates to more than the {} bytes its zip header declares", name, st.size));
      }
      out.append(buf, static_cast<std::size_t>(n));
    }
    zip_fclose(zf);
    if (out.size() != st.size)
      fail(file_, fmt::format("{}: {} bytes inflated, the zip header declares {}", name, out.size(), st.size));
    return out;
  }

 private:
  std::filesystem::path file_;
  zip_t* za_ = nullptr;
  std::string base_;
};

std::string read_whole_file(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) fail(file, "read error");
  return std::move(ss).str();
}

// ---- XML helpers: element names compared without their namespace prefix ----

std::string_view local_name(const char* n) {
  std::string_view s(n);
  const auto c = s.find(':');
  return c == std::string_view::npos ? s : s.substr(c + 1);
}

pugi::xml_node child(pugi::xml_node n, std::string_view name) {
  for (pugi::xml_node c = n.first_child(); c; c = c.next_sibling())
    if (c.type() == pugi::node_element && local_name(c.name()) == name) return c;
  return {};
}

std::string trimmed(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return std::string(s);
}

std::string text_of(pugi::xml_node n) { return n ? trimmed(n.child_value()) : std::string(); }

// One axis of Record1/Axes.
struct Axis {
  char type = 'I';  // I incremental, A absolute
  char data = 'D';  // I L F D
  bool has_data_type = false;
  double inc_mm = 1000.0;  // Increment (m) in mm; 1 m when absent (older files leave it out on CZ)
  double off_mm = 0.0;
  bool unit_inc = true;  // Increment is exactly 1 (metre values): text values convert with one rounding
  bool zero_off = true;
  double coord(double raw) const { return zero_off ? inc_mm * raw : off_mm + inc_mm * raw; }
  std::size_t size() const { return data == 'I' ? 2 : data == 'L' ? 4 : data == 'F' ? 4 : 8; }
};

struct XmlContext {
  const std::filesystem::path& file;
  const std::string& xml;
  std::string where(pugi::xml_node n) const {
    // main.xml:LINE for the element's position in the text.
    const std::ptrdiff_t off = n.offset_debug();
    int line = 1;
    if (off > 0 && static_cast<std::size_t>(off) <= xml.size())
      line += static_cast<int>(std::count(xml.begin(), xml.begin() + off, '\n'));
    return fmt::format("main.xml:{}", line);
  }
  [[noreturn]] void error(pugi::xml_node n, const std::string& path, const std::string& what) const {
    fail(file, where(n) + ": " + path + ": " + what);
  }
};

Axis parse_axis(const XmlContext& cx, pugi::xml_node axes, const char* name) {
  const std::string path = std::string("Record1/Axes/") + name;
  const pugi::xml_node n = child(axes, name);
  if (!n) cx.error(axes, path, "missing (ISO 5436-2 requires CX, CY and CZ)");
  Axis a;
  const std::string t = text_of(child(n, "AxisType"));
  if (t != "I" && t != "A")
    cx.error(n, path + "/AxisType", "expected I (incremental) or A (absolute), found \"" + t + "\"");
  a.type = t[0];
  if (const pugi::xml_node d = child(n, "DataType")) {
    const std::string dt = text_of(d);
    if (dt != "I" && dt != "L" && dt != "F" && dt != "D")
      cx.error(d, path + "/DataType",
               "expected I (int16), L (int32), F (float32) or D (float64), found \"" + dt + "\"");
    a.data = dt[0];
    a.has_data_type = true;
  }
  if (const pugi::xml_node inc = child(n, "Increment")) {
    const std::string s = text_of(inc);
    const auto v = parse_decimal_scaled(s, 3);
    if (!v || !std::isfinite(*v) || *v == 0.0)
      cx.error(inc, path + "/Increment", "expected a non-zero number of metres, found \"" + s + "\"");
    a.inc_mm = *v;
    a.unit_inc = *v == 1000.0;
  }
  // An empty <Offset/> (x3ptools writes one on CZ) is no offset.
  if (const pugi::xml_node off = child(n, "Offset"); off && !text_of(off).empty()) {
    const std::string s = text_of(off);
    const auto v = parse_decimal_scaled(s, 3);
    if (!v || !std::isfinite(*v)) cx.error(off, path + "/Offset", "expected a number of metres, found \"" + s + "\"");
    a.off_mm = *v;
    a.zero_off = *v == 0.0;
  }
  if (a.type == 'A' && !a.has_data_type && std::string(name) != "CZ")
    cx.error(n, path + "/DataType", "an absolute axis needs a data type (I, L, F or D)");
  return a;
}

std::uint64_t parse_count(const XmlContext& cx, pugi::xml_node parent, const char* name, const std::string& path) {
  const pugi::xml_node n = child(parent, name);
  const std::string s = text_of(n);
  if (!n || s.empty() || s.size() > 18 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    cx.error(n ? n : parent, path + "/" + name, "expected a positive integer, found \"" + s + "\"");
  const std::uint64_t v = std::stoull(s);
  if (v == 0) cx.error(n, path + "/" + name, "must be at least 1");
  if (v > kMaxGridPoints)
    cx.error(n, path + "/" + name, fmt::format("{} is more than the {} points vmsim accepts", v, kMaxGridPoints));
  return v;
}

template <typename T>
T load_le(const char* p) {
  // The data files are little-endian (ISO 5436-2); this machine is too (x86-64), so a memcpy reads them.
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

double decode(const char* p, char type) {
  switch (type) {
    case 'I':
      return load_le<std::int16_t>(p);
    case 'L':
      return load_le<std::int32_t>(p);
    case 'F':
      return load_le<float>(p);
    default:
      return load_le<double>(p);
  }
}

std::string hex_lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Absolute x (or y) values of a matrix, per column (row), must lie on a regular lattice for a HeightGrid.
void regular_axis(const std::filesystem::path& file, const char* axis, const std::vector<double>& value,
                  const std::vector<int>& seen, double& origin, double& step, double fallback_step) {
  const std::size_t n = value.size();
  std::ptrdiff_t first = -1, last = -1;
  for (std::size_t k = 0; k < n; ++k)
    if (seen[k]) {
      if (first < 0) first = static_cast<std::ptrdiff_t>(k);
      last = static_cast<std::ptrdiff_t>(k);
    }
  if (first < 0) fail(file, fmt::format("absolute {} axis: no valid point gives a coordinate", axis));
  if (first == last) {
    step = std::abs(fallback_step);
    origin = value[static_cast<std::size_t>(first)] - static_cast<double>(first) * step;
    return;
  }
  step = (value[static_cast<std::size_t>(last)] - value[static_cast<std::size_t>(first)]) /
         static_cast<double>(last - first);
  if (!(step > 0) || !std::isfinite(step))
    fail(file, fmt::format("absolute {} axis: coordinates do not increase along the matrix (step {} mm)", axis, step));
  origin = value[static_cast<std::size_t>(first)] - static_cast<double>(first) * step;
  for (std::size_t k = 0; k < n; ++k) {
    if (!seen[k]) continue;
    const double expect = origin + static_cast<double>(k) * step;
    if (std::abs(value[k] - expect) > 1e-3 * step)
      fail(file, fmt::format("absolute {} axis: index {} is at {:.9g} mm, {:.9g} mm expected on a regular grid; "
                             "vmsim needs regular steps",
                             axis, k, value[k], expect));
  }
}

}  // namespace

X3pData read_x3p(const std::filesystem::path& file, const X3pReadOptions& options) {
  const std::string bytes = read_whole_file(file);
  if (bytes.size() < 4 || bytes.compare(0, 4, "PK\x03\x04") != 0)
    fail(file, "not an X3P file: it does not start like a zip archive (PK\\3\\4)");
  ZipReader zip(file, bytes);

  // main.xml sits at the archive's root in a standard file; some tools (x3ptools, archives made on macOS) put the
  // whole X3P under a folder, next to __MACOSX/ resource forks and .DS_Store files. The one main.xml outside that
  // junk is taken wherever it is, and the data links are read relative to its folder.
  std::vector<std::string> notes;
  const std::vector<std::string> entries = zip.names();
  const auto is_junk = [](const std::string& e) {
    const std::string base = e.substr(e.find_last_of('/') == std::string::npos ? 0 : e.find_last_of('/') + 1);
    return e.rfind("__MACOSX/", 0) == 0 || base.rfind("._", 0) == 0 || base == ".DS_Store";
  };
  std::vector<std::string> mains;
  for (const std::string& e : entries) {
    if (is_junk(e)) continue;
    const std::size_t slash = e.find_last_of('/');
    std::string base = slash == std::string::npos ? e : e.substr(slash + 1);
    for (char& c : base) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (base == "main.xml") mains.push_back(e);
  }
  if (mains.empty()) fail(file, "main.xml: missing from the zip (every X3P file has one)");
  if (mains.size() > 1)
    fail(file, fmt::format("the zip holds {} main.xml files ({}); an X3P file has one", mains.size(), [&] {
           std::string l;
           for (const auto& m : mains) l += (l.empty() ? "" : ", ") + m;
           return l;
         }()));
  const std::string main_name = mains.front();
  const std::string folder = main_name.substr(0, main_name.size() - std::string("main.xml").size());
  zip.set_base(folder);
  if (!folder.empty())
    notes.push_back("main.xml is in the folder \"" + folder +
                    "\" of the zip, not at its root; vmsim read the X3P from there");
  const auto main_idx = zip.find(main_name.substr(folder.size()));
  if (!main_idx) fail(file, "main.xml: missing from the zip (every X3P file has one)");
  std::vector<std::string> used = {zip.name(*main_idx)};
  const std::string xml = zip.read(*main_idx, main_name, kMaxXmlBytes);

  pugi::xml_document doc;
  const pugi::xml_parse_result pr = doc.load_buffer(xml.data(), xml.size(), pugi::parse_default, pugi::encoding_auto);
  if (!pr) {
    const int line =
        1 + static_cast<int>(std::count(
                xml.begin(),
                xml.begin() + std::clamp<std::ptrdiff_t>(pr.offset, 0, static_cast<std::ptrdiff_t>(xml.size())), '\n'));
    fail(file, fmt::format("main.xml:{}: not well-formed XML: {}", line, pr.description()));
  }
  const XmlContext cx{file, xml};
  const pugi::xml_node root = doc.document_element();
  if (!root || (local_name(root.name()) != "ISO5436_2" && local_name(root.name()) != "ISO5436"))
    fail(file, std::string("main.xml: the root element is \"") + (root ? root.name() : "") + "\", expected ISO5436_2");
  if (local_name(root.name()) == "ISO5436")
    notes.push_back("main.xml's root element is ISO5436 (as x3ptools writes it), read as ISO5436_2");

  X3pData out;
  X3pMeta& meta = out.meta;

  // ---- Record1: feature type and axes ----
  const pugi::xml_node r1 = child(root, "Record1");
  if (!r1) cx.error(root, "Record1", "missing");
  meta.revision = text_of(child(r1, "Revision"));
  meta.feature_type = text_of(child(r1, "FeatureType"));
  if (meta.feature_type != "SUR" && meta.feature_type != "PRF" && meta.feature_type != "PCL")
    cx.error(r1, "Record1/FeatureType", "expected SUR, PRF or PCL, found \"" + meta.feature_type + "\"");
  const pugi::xml_node axes = child(r1, "Axes");
  if (!axes) cx.error(r1, "Record1/Axes", "missing");
  const Axis ax[3] = {parse_axis(cx, axes, "CX"), parse_axis(cx, axes, "CY"), parse_axis(cx, axes, "CZ")};
  if (ax[2].type != 'A') cx.error(axes, "Record1/Axes/CZ/AxisType", "the z axis must be absolute (A)");
  for (int k = 0; k < 3; ++k) {
    meta.axis_type[static_cast<std::size_t>(k)] = ax[k].type;
    meta.data_type[static_cast<std::size_t>(k)] = ax[k].has_data_type ? ax[k].data : '\0';
  }
  if (const pugi::xml_node rot = child(axes, "Rotation")) {
    static const char* names[9] = {"r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33"};
    for (int k = 0; k < 9; ++k) {
      const std::string s = text_of(child(rot, names[k]));
      const auto v = parse_decimal_scaled(s);
      if (!v) cx.error(rot, std::string("Record1/Axes/Rotation/") + names[k], "expected a number, found \"" + s + "\"");
      if (std::abs(*v - ((k % 4 == 0) ? 1.0 : 0.0)) > 1e-12) meta.rotation_identity = false;
    }
  }

  // ---- Record2: metadata (optional) ----
  if (const pugi::xml_node r2 = child(root, "Record2")) {
    meta.date = text_of(child(r2, "Date"));
    meta.creator = text_of(child(r2, "Creator"));
    const pugi::xml_node ins = child(r2, "Instrument");
    meta.manufacturer = text_of(child(ins, "Manufacturer"));
    meta.model = text_of(child(ins, "Model"));
    meta.serial = text_of(child(ins, "Serial"));
    meta.version = text_of(child(ins, "Version"));
    const pugi::xml_node ps = child(r2, "ProbingSystem");
    meta.probing_type = text_of(child(ps, "Type"));
    meta.probing_id = text_of(child(ps, "Identification"));
    meta.comment = text_of(child(r2, "Comment"));
  }

  // ---- Record3: dimensions and data ----
  const pugi::xml_node r3 = child(root, "Record3");
  if (!r3) cx.error(root, "Record3", "missing (it holds the data)");
  const pugi::xml_node mdim = child(r3, "MatrixDimension");
  const pugi::xml_node ldim = child(r3, "ListDimension");
  const bool matrix = static_cast<bool>(mdim);
  std::uint64_t nx = 0, ny = 0, npoints = 0;
  if (matrix) {
    nx = parse_count(cx, mdim, "SizeX", "Record3/MatrixDimension");
    ny = parse_count(cx, mdim, "SizeY", "Record3/MatrixDimension");
    const std::uint64_t nz = parse_count(cx, mdim, "SizeZ", "Record3/MatrixDimension");
    if (nz != 1)
      cx.error(mdim, "Record3/MatrixDimension/SizeZ", fmt::format("{} layers; vmsim reads single-layer data (1)", nz));
    if (nx > kMaxGridPoints / ny)
      cx.error(mdim, "Record3/MatrixDimension",
               fmt::format("{} x {} points is more than the {} vmsim accepts", nx, ny, kMaxGridPoints));
    npoints = nx * ny;
    if (meta.feature_type == "PCL")
      cx.error(mdim, "Record1/FeatureType", "PCL (point list) data must use ListDimension");
  } else if (ldim) {
    npoints = parse_count(cx, r3, "ListDimension", "Record3");
    if (meta.feature_type != "PCL")
      cx.error(ldim, "Record3/ListDimension", "a list of points needs FeatureType PCL, found " + meta.feature_type);
  } else {
    cx.error(r3, "Record3", "neither MatrixDimension nor ListDimension is given");
  }

  // Within the point limit a scan can still need more memory than the machine has (2^28 points: 8.5 GB, issue 18):
  // the reader's own need - the stored records (up to 24 B), the coordinates (up to 24 B), the validity (1 B) and
  // the height grid (8 B) per point - against the memory available, before anything is allocated.
  {
    const double need = static_cast<double>(npoints) * 57.0;
    const core::AvailableMemory avail = core::available_memory();
    if (need > avail.bytes)
      fail(file, fmt::format("{} points need about {} to read, while {} is available ({}): read it on a machine with "
                             "more memory, or crop or resample the scan first",
                             npoints, core::format_bytes(need), core::format_bytes(avail.bytes), avail.source));
  }

  // Which axes are stored per point, in order: the absolute ones (and, in a list, every axis).
  std::vector<int> stored;
  for (int k = 0; k < 3; ++k)
    if (ax[k].type == 'A') stored.push_back(k);
  // Per point: the x, y, z coordinates (mm) of the stored axes, and whether the point is valid. Allocated only
  // once the data are known to hold as many points as the dimensions declare.
  std::vector<double> coord[3];
  std::vector<std::uint8_t> valid;
  const auto allocate = [&]() {
    for (int k : stored) coord[k].assign(npoints, 0.0);
    valid.assign(npoints, 1);
  };

  const pugi::xml_node link = child(r3, "DataLink");
  const pugi::xml_node list = child(r3, "DataList");
  std::string zcorr;  // vendor extension, if any
  if (link) {
    meta.binary = true;
    std::size_t record = 0;
    for (int k : stored) record += ax[k].size();
    const std::string data_name = text_of(child(link, "PointDataLink"));
    if (data_name.empty()) cx.error(link, "Record3/DataLink/PointDataLink", "missing or empty");
    const auto di = zip.find(data_name);
    if (!di) cx.error(link, "Record3/DataLink/PointDataLink", "\"" + data_name + "\" is not in the zip");
    const std::string data = zip.read(*di, data_name, kMaxGridPoints * 24, npoints * record);
    used.push_back(zip.name(*di));
    allocate();
    if (options.verify_checksums) {
      const std::string want = hex_lower(text_of(child(link, "MD5ChecksumPointData")));
      if (!want.empty() && want != core::md5_hex(data))
        cx.error(
            link, "Record3/DataLink/MD5ChecksumPointData",
            "MD5 of " + data_name + " is " + core::md5_hex(data) + ", the file states " + want + " (corrupt data)");
    }
    const char* p = data.data();
    for (std::uint64_t i = 0; i < npoints; ++i)
      for (int k : stored) {
        coord[k][i] = ax[k].coord(decode(p, ax[k].data));
        p += ax[k].size();
      }
    const std::string valid_name = text_of(child(link, "ValidPointsLink"));
    if (!valid_name.empty()) {
      const auto vi = zip.find(valid_name);
      if (!vi) cx.error(link, "Record3/DataLink/ValidPointsLink", "\"" + valid_name + "\" is not in the zip");
      const std::string bits = zip.read(*vi, valid_name, kMaxGridPoints / 8 + 1, (npoints + 7) / 8);
      used.push_back(zip.name(*vi));
      if (options.verify_checksums) {
        const std::string want = hex_lower(text_of(child(link, "MD5ChecksumValidPoints")));
        if (!want.empty() && want != core::md5_hex(bits))
          cx.error(link, "Record3/DataLink/MD5ChecksumValidPoints",
                   "MD5 of " + valid_name + " is " + core::md5_hex(bits) + ", the file states " + want);
      }
      meta.valid_mask = true;
      for (std::uint64_t i = 0; i < npoints; ++i)
        if (!((static_cast<unsigned char>(bits[i / 8]) >> (i % 8)) & 1u)) valid[i] = 0;
    }
    // vmsim's own files: the mm heights exactly (see write_x3p).
    const pugi::xml_node vendor = child(root, "VendorSpecificID");
    if (vendor && text_of(vendor) == kVendorUri && matrix && stored.size() == 1 && ax[2].data == 'D' &&
        ax[2].unit_inc && ax[2].zero_off)
      if (const auto ci = zip.find(kVendorEntry))
        zcorr = zip.read(*ci, kVendorEntry, kMaxGridPoints, npoints), used.push_back(zip.name(*ci));
  } else if (list) {
    std::uint64_t count = 0;
    for (pugi::xml_node d = list.first_child(); d; d = d.next_sibling())
      if (d.type() == pugi::node_element) ++count;
    if (count != npoints)
      cx.error(list, "Record3/DataList", fmt::format("{} Datum elements, the dimensions declare {}", count, npoints));
    allocate();
    std::uint64_t i = 0;
    for (pugi::xml_node d = list.first_child(); d; d = d.next_sibling()) {
      if (d.type() != pugi::node_element) continue;
      if (local_name(d.name()) != "Datum")
        cx.error(d, "Record3/DataList", std::string("unexpected element ") + d.name());
      if (i >= npoints)
        cx.error(d, "Record3/DataList", fmt::format("more than the {} Datum elements the dimensions declare", npoints));
      const std::string s = text_of(d);
      if (s.empty()) {  // an empty <Datum/> is a missing point (ISO 5436-2)
        valid[i++] = 0;
        continue;
      }
      std::vector<std::string> parts;
      std::size_t start = 0;
      for (;;) {
        const std::size_t semi = s.find(';', start);
        parts.push_back(s.substr(start, semi == std::string::npos ? std::string::npos : semi - start));
        if (semi == std::string::npos) break;
        start = semi + 1;
        if (parts.size() > 3) break;
      }
      // The values of the absolute axes, in x y z order; some writers list every axis (incremental ones as indices).
      std::vector<int> order;
      if (parts.size() == stored.size())
        order = stored;
      else if (parts.size() == 3)
        order = {0, 1, 2};
      else
        cx.error(d, "Record3/DataList/Datum",
                 fmt::format("\"{}\": {} values, expected {} (one per absolute axis, separated by ;)", s, parts.size(),
                             stored.size()));
      for (std::size_t c = 0; c < order.size(); ++c) {
        const int k = order[c];
        if (ax[k].type != 'A') continue;  // an incremental axis' index: its position comes from the point index
        // Metre values (Increment 1) convert with one rounding; scaled ones go through the axis' formula.
        const auto v = ax[k].unit_inc ? parse_decimal_scaled(parts[c], 3) : parse_decimal_scaled(parts[c]);
        if (!v) cx.error(d, "Record3/DataList/Datum", "\"" + s + "\": \"" + parts[c] + "\" is not a number");
        coord[k][i] = ax[k].unit_inc ? (ax[k].zero_off ? *v : ax[k].off_mm + *v) : ax[k].coord(*v);
      }
      ++i;
    }
    if (i != npoints)
      cx.error(list, "Record3/DataList", fmt::format("{} Datum elements, the dimensions declare {}", i, npoints));
  } else {
    cx.error(r3, "Record3", "neither DataLink nor DataList is given");
  }

  // ---- Record4: checksum of main.xml ----
  const pugi::xml_node r4 = child(root, "Record4");
  const std::string sum_name = text_of(child(r4, "ChecksumFile"));
  if (options.verify_checksums && !sum_name.empty()) {
    if (const auto si = zip.find(sum_name)) {
      const std::string sum = zip.read(*si, sum_name, 4096);
      used.push_back(zip.name(*si));
      std::string want = trimmed(sum).substr(0, 32);
      want = hex_lower(want);
      const std::string have = core::md5_hex(xml);
      if (want != have)
        fail(file, sum_name + ": states MD5 " + want + " for main.xml, which has " + have + " (the file is corrupt)");
      meta.main_checksum_checked = true;
    }
  }

  // ---- assemble ----
  for (std::uint64_t i = 0; i < npoints; ++i)
    if (valid[i] && !std::isfinite(coord[2][i])) valid[i] = 0;
  if (!zcorr.empty())
    for (std::uint64_t i = 0; i < npoints; ++i) {
      const int k = static_cast<signed char>(zcorr[i]);
      if (k < -4 || k > 4) fail(file, fmt::format("{}: byte {} is {}, expected -4..4", kVendorEntry, i, k));
      double& z = coord[2][i];
      for (int s = 0; s < std::abs(k); ++s) z = std::nextafter(z, k > 0 ? HUGE_VAL : -HUGE_VAL);
    }
  meta.invalid_points = static_cast<std::size_t>(std::count(valid.begin(), valid.end(), 0));
  {
    // Say what was left aside: macOS junk, and entries main.xml does not name (an R package's annotation image).
    std::vector<std::string> junk, other;
    for (const std::string& e : entries) {
      if (e.empty() || e.back() == '/' || std::find(used.begin(), used.end(), e) != used.end()) continue;
      (is_junk(e) ? junk : other).push_back(e);
    }
    const auto join = [](const std::vector<std::string>& v) {
      std::string l;
      for (std::size_t k = 0; k < v.size() && k < 8; ++k) l += (l.empty() ? "" : ", ") + v[k];
      if (v.size() > 8) l += fmt::format(" and {} more", v.size() - 8);
      return l;
    };
    if (!junk.empty())
      notes.push_back("ignored " + std::to_string(junk.size()) + " macOS metadata entries (" + join(junk) + ")");
    if (!other.empty()) notes.push_back("ignored entries main.xml does not name: " + join(other));
  }
  meta.notes = notes;

  if (matrix) {
    core::HeightGrid& g = out.grid;
    g.z_mm.resize(static_cast<Eigen::Index>(ny), static_cast<Eigen::Index>(nx));
    for (std::uint64_t i = 0; i < npoints; ++i)
      g.z_mm.data()[i] = valid[i] ? coord[2][i] : std::numeric_limits<double>::quiet_NaN();
    for (int k = 0; k < 2; ++k) {
      const Axis& a = ax[k];
      double& origin = k == 0 ? g.x0_mm : g.y0_mm;
      double& step = k == 0 ? g.dx_mm : g.dy_mm;
      if (a.type == 'I') {
        origin = a.off_mm;
        step = a.inc_mm;
        if (!(step > 0))
          fail(file, fmt::format("Record1/Axes/{}/Increment: {} m; vmsim needs increasing coordinates (> 0)",
                                 k == 0 ? "CX" : "CY", format_scaled(step, -3)));
        continue;
      }
      // Absolute x (y) in a matrix: one value per column (row) on a regular lattice.
      const std::uint64_t n = k == 0 ? nx : ny;
      std::vector<double> value(n, 0.0);
      std::vector<int> seen(n, 0);
      for (std::uint64_t i = 0; i < npoints; ++i) {
        if (!valid[i] || !std::isfinite(coord[k][i])) continue;
        const std::uint64_t c = k == 0 ? i % nx : i / nx;
        if (!seen[c])
          value[c] = coord[k][i], seen[c] = 1;
        else if (std::abs(coord[k][i] - value[c]) > 1e-9 * std::max(1.0, std::abs(value[c])))
          fail(file, fmt::format("absolute {} axis: points of matrix {} {} have different coordinates ({:.9g} and "
                                 "{:.9g} mm); vmsim needs a regular grid",
                                 k == 0 ? "CX" : "CY", k == 0 ? "column" : "row", c, value[c], coord[k][i]));
      }
      regular_axis(file, k == 0 ? "CX" : "CY", value, seen, origin, step, a.inc_mm);
    }
  } else {
    // Point list: positions of incremental axes come from the index (openGPS's convention).
    std::vector<Eigen::Index> keep;
    for (std::uint64_t i = 0; i < npoints; ++i)
      if (valid[i]) keep.push_back(static_cast<Eigen::Index>(i));
    out.points_mm.resize(static_cast<Eigen::Index>(keep.size()), 3);
    for (std::size_t r = 0; r < keep.size(); ++r)
      for (int k = 0; k < 3; ++k) {
        const auto i = static_cast<std::size_t>(keep[r]);
        out.points_mm(static_cast<Eigen::Index>(r), k) =
            ax[k].type == 'A' ? coord[k][i] : ax[k].coord(static_cast<double>(i));
      }
    try {
      out.grid = points_to_grid(out.points_mm, file.string());
    } catch (const core::Error&) {
      out.grid = core::HeightGrid{};  // not on a lattice: the points are still there
      out.grid.z_mm.resize(0, 0);
    }
  }
  return out;
}

// ---- writing ----

namespace {

std::string xml_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&':
        o += "&amp;";
        break;
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '"':
        o += "&quot;";
        break;
      default:
        // Control characters are not allowed in XML 1.0 text.
        if (static_cast<unsigned char>(c) < 0x20 && c != '\n' && c != '\t' && c != '\r')
          o += ' ';
        else
          o += c;
    }
  }
  return o;
}

std::string utc_now() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S+00:00", &tm);
  return buf;
}

// Builds a zip in memory (so the file is then written atomically, as every vmsim output).
class ZipWriter {
 public:
  explicit ZipWriter(const std::filesystem::path& file) : file_(file) {
    zip_error_t ze;
    zip_error_init(&ze);
    src_ = zip_source_buffer_create(nullptr, 0, 0, &ze);
    if (!src_) fail(file, std::string("cannot create a zip in memory: ") + zip_error_strerror(&ze));
    zip_source_keep(src_);
    za_ = zip_open_from_source(src_, ZIP_TRUNCATE, &ze);
    if (!za_) fail(file, std::string("cannot create a zip in memory: ") + zip_error_strerror(&ze));
    zip_error_fini(&ze);
  }
  ~ZipWriter() {
    if (za_) zip_discard(za_);
    if (src_) zip_source_free(src_);
  }
  ZipWriter(const ZipWriter&) = delete;
  ZipWriter& operator=(const ZipWriter&) = delete;

  void dir(const char* name) {
    if (zip_dir_add(za_, name, ZIP_FL_ENC_UTF_8) < 0) fail(file_, std::string("zip: ") + zip_strerror(za_));
  }
  // `data` must live until finish(). Level 0 stores the entry uncompressed.
  void add(const char* name, const std::string& data, int level) {
    zip_source_t* s = zip_source_buffer(za_, data.data(), data.size(), 0);
    if (!s) fail(file_, std::string("zip: ") + zip_strerror(za_));
    const zip_int64_t i = zip_file_add(za_, name, s, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE);
    if (i < 0) {
      zip_source_free(s);
      fail(file_, std::string("zip: ") + zip_strerror(za_));
    }
    if (zip_set_file_compression(za_, static_cast<zip_uint64_t>(i), level > 0 ? ZIP_CM_DEFLATE : ZIP_CM_STORE,
                                 static_cast<zip_uint32_t>(std::clamp(level, 1, 9))) != 0)
      fail(file_, std::string("zip: ") + zip_strerror(za_));
  }
  std::string finish() {
    if (zip_close(za_) != 0) fail(file_, std::string("zip: ") + zip_strerror(za_));
    za_ = nullptr;
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_source_stat(src_, &st) != 0 || zip_source_open(src_) != 0)
      fail(file_, "zip: cannot read back the archive built in memory");
    std::string out(static_cast<std::size_t>(st.size), '\0');
    const zip_int64_t n = zip_source_read(src_, out.data(), st.size);
    zip_source_close(src_);
    if (n < 0 || static_cast<zip_uint64_t>(n) != st.size) fail(file_, "zip: short read of the archive built in memory");
    return out;
  }

 private:
  std::filesystem::path file_;
  zip_source_t* src_ = nullptr;
  zip_t* za_ = nullptr;
};

}  // namespace

void write_x3p(const std::filesystem::path& file, const core::HeightGrid& g, const X3pWriteOptions& o) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  if (nx < 1 || ny < 1) fail(file, "cannot write an empty grid as X3P");
  if (!(g.dx_mm > 0) || !(g.dy_mm > 0) || !std::isfinite(g.x0_mm) || !std::isfinite(g.y0_mm))
    fail(file, "cannot write X3P: the grid's spacing must be positive and its origin finite");
  const std::size_t n = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);

  // data.bin: metres, float64 little-endian; valid.bin: a bit per point; the vendor entry: ulp corrections.
  std::string data(n * 8, '\0'), bits((n + 7) / 8, '\0'), corr(n, '\0');
  std::size_t invalid = 0;
  bool any_corr = false;
  const double* z = g.z_mm.data();
  for (std::size_t i = 0; i < n; ++i) {
    const bool ok = std::isfinite(z[i]);
    const double m = ok ? z[i] / 1000.0 : std::numeric_limits<double>::quiet_NaN();
    std::memcpy(&data[i * 8], &m, 8);
    if (ok) {
      bits[i / 8] = static_cast<char>(static_cast<unsigned char>(bits[i / 8]) | (1u << (i % 8)));
      // What the reader computes (1000 * m, CZ Increment 1 m), and the steps from there to z.
      double back = 1000.0 * m;
      int k = 0;
      const auto same = [&] { return std::bit_cast<std::uint64_t>(back) == std::bit_cast<std::uint64_t>(z[i]); };
      while (!same() && k < 4 && k > -4) {
        const int dir = z[i] > back ? 1 : -1;
        back = std::nextafter(back, dir > 0 ? HUGE_VAL : -HUGE_VAL);
        k += dir;
      }
      if (!same()) k = 0;  // cannot happen for finite z; the metre value stands
      corr[i] = static_cast<char>(static_cast<signed char>(k));
      any_corr = any_corr || k != 0;
    } else {
      ++invalid;
    }
  }

  const std::string date = o.date.empty() ? utc_now() : o.date;
  std::string x;
  x += "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\" ?>\n";
  x += "<p:ISO5436_2 xmlns:p=\"http://www.opengps.eu/2008/ISO5436_2\" "
       "xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" "
       "xsi:schemaLocation=\"http://www.opengps.eu/2008/ISO5436_2 "
       "http://www.opengps.eu/2008/ISO5436_2/ISO5436_2.xsd\">\n";
  x += "  <Record1>\n    <Revision>ISO5436 - 2000</Revision>\n    <FeatureType>SUR</FeatureType>\n    <Axes>\n";
  const auto axis = [&](const char* name, const char* type, double inc_mm, double off_mm) {
    x += fmt::format(
        "      <{0}>\n        <AxisType>{1}</AxisType>\n        <DataType>D</DataType>\n"
        "        <Increment>{2}</Increment>\n        <Offset>{3}</Offset>\n      </{0}>\n",
        name, type, format_scaled(inc_mm, -3), format_scaled(off_mm, -3));
  };
  axis("CX", "I", g.dx_mm, g.x0_mm);
  axis("CY", "I", g.dy_mm, g.y0_mm);
  axis("CZ", "A", 1000.0, 0.0);  // heights in metres: Increment 1, Offset 0
  x += "    </Axes>\n  </Record1>\n";
  x += "  <Record2>\n";
  x += "    <Date>" + xml_escape(date) + "</Date>\n";
  x += "    <Creator>" + xml_escape(o.creator) + "</Creator>\n";
  x += "    <Instrument>\n      <Manufacturer>vmsim</Manufacturer>\n";
  x += "      <Model>" + xml_escape(o.model) + "</Model>\n";
  x += "      <Serial>not available</Serial>\n";
  x += "      <Version>" + xml_escape(o.version) + "</Version>\n    </Instrument>\n";
  // Optional in the 2020 schema, required in the 2007 one that older readers validate against.
  x += "    <CalibrationDate>" + xml_escape(date) + "</CalibrationDate>\n";
  x += "    <ProbingSystem>\n      <Type>" + xml_escape(o.probing_type) + "</Type>\n";
  x += "      <Identification>" + xml_escape(o.probing_id) + "</Identification>\n    </ProbingSystem>\n";
  x += "    <Comment>" + xml_escape(o.comment) + "</Comment>\n";
  x += "  </Record2>\n";
  x += fmt::format(
      "  <Record3>\n    <MatrixDimension>\n      <SizeX>{}</SizeX>\n      <SizeY>{}</SizeY>\n"
      "      <SizeZ>1</SizeZ>\n    </MatrixDimension>\n",
      nx, ny);
  x += "    <DataLink>\n      <PointDataLink>bindata/data.bin</PointDataLink>\n";
  x += "      <MD5ChecksumPointData>" + core::md5_hex(data) + "</MD5ChecksumPointData>\n";
  if (invalid > 0) {
    x += "      <ValidPointsLink>bindata/valid.bin</ValidPointsLink>\n";
    x += "      <MD5ChecksumValidPoints>" + core::md5_hex(bits) + "</MD5ChecksumValidPoints>\n";
  }
  x += "    </DataLink>\n  </Record3>\n";
  x += "  <Record4>\n    <ChecksumFile>md5checksum.hex</ChecksumFile>\n  </Record4>\n";
  if (any_corr) x += std::string("  <VendorSpecificID>") + kVendorUri + "</VendorSpecificID>\n";
  x += "</p:ISO5436_2>\n";
  const std::string sum = core::md5_hex(x) + " *main.xml\n";  // md5sum's binary-mode line, as openGPS writes it

  ZipWriter zw(file);
  zw.add("main.xml", x, 6);  // first, where readers that sniff the archive look
  zw.dir("bindata");
  zw.add("bindata/data.bin", data, o.compression_level);
  if (invalid > 0) zw.add("bindata/valid.bin", bits, 6);
  if (any_corr) {
    zw.dir("vmsim");
    // Almost all zeros: small at any level (level 9 cost 60 % of this writer's CPU to save 0.17 % of the file).
    zw.add(kVendorEntry, corr, 1);
  }
  zw.add("md5checksum.hex", sum, 6);
  core::write_file_atomic(file, zw.finish());
}

}  // namespace vmsim::metrology
