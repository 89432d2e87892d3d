#include "metrology/surface_io.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"
#include "metrology/bcr.hpp"
#include "metrology/dektak.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/gzip.hpp"
#include "metrology/sdf.hpp"
#include "metrology/sur.hpp"
#include "metrology/x3p.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>
#include <string>

namespace vmsim::metrology {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

}  // namespace

namespace {

void add_note(SurfaceFile& out, const std::string& s) {
  if (!s.empty()) out.note += (out.note.empty() ? "" : "; ") + s;
}

void set_profile(SurfaceFile& out, LineScan p) {
  out.grid = grid_of_line_scan(p);
  out.profile = std::move(p);
}

// The formats that can come from bytes (a gzip-inflated file); `ext` is the name's extension without ".gz".
SurfaceFile read_bytes(const std::string& bytes, const std::string& name, const std::string& ext) {
  SurfaceFile out;
  const std::string_view head(bytes.data(), std::min<std::size_t>(bytes.size(), 4096));
  if (head.rfind("DIGITAL SURF", 0) == 0 || head.rfind("DSCOMPRESSED", 0) == 0) {
    SurData d = read_sur_bytes(bytes, name);
    out.format = "sur";
    out.note = d.note;
    if (d.profile)
      set_profile(out, line_scan_of_row(d.grid));
    else
      out.grid = std::move(d.grid);
    return out;
  }
  if (looks_like_bcr(head)) {
    out.grid = read_bcr_bytes(bytes, name);
    out.format = "bcr";
    return out;
  }
  if (head.rfind("PK\x03\x04", 0) == 0 || head.rfind("aISO", 0) == 0 || head.rfind("bISO", 0) == 0)
    throw core::Error(name + ": a compressed X3P or SDF file; vmsim reads these uncompressed (gunzip it first)");
  if (std::any_of(head.begin(), head.end(), [](char c) { return c == '\0'; }))
    throw core::Error(name +
                      ": binary data of unknown format (vmsim reads X3P, .sur, SDF, BCR-STM, CSV and ASCII grids)");
  if (looks_like_dektak(head)) {
    DektakData d = read_dektak_csv(bytes, name);
    out.format = "dektak";
    out.note = d.note;
    set_profile(out, std::move(d.profile));
    return out;
  }
  std::istringstream in(bytes);
  if (head.find("# x0_mm=") != std::string_view::npos) {
    out.grid = read_height_csv(in, name);
    out.format = "csv";
  } else if (ext == ".xyz" || ext == ".asc" || ext == ".pts") {
    out.grid = read_xyz_grid(in, name);
    out.format = "xyz";
  } else {
    out.grid = read_matrix_grid(in, name);
    out.format = "matrix";
  }
  return out;
}

}  // namespace

SurfaceFile read_surface_file(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  in.close();
  SurfaceFile out;
  if (looks_like_gzip(head)) {
    std::filesystem::path inner = file;
    if (lower_ext(inner) == ".gz") inner.replace_extension();
    out = read_bytes(gunzip_file(file), file.string(), lower_ext(inner));
    out.format += "+gzip";
    return out;
  }
  if (head.rfind("PK\x03\x04", 0) == 0) {
    X3pData d = read_x3p(file);
    if (d.grid.z_mm.size() == 0)
      throw core::Error(file.string() +
                        ": the X3P point list does not lie on a regular x/y grid; vmsim compares grids");
    out.format = "x3p";
    for (const std::string& n : d.meta.notes) add_note(out, n);
    if (!d.meta.rotation_identity)
      add_note(out, "the file's Record1/Axes/Rotation is not the identity and was not applied");
    if (d.meta.feature_type == "PRF" && d.grid.ny() == 1)
      set_profile(out, line_scan_of_row(d.grid));
    else
      out.grid = std::move(d.grid);
    return out;
  }
  if (head.rfind("aISO", 0) == 0 || head.rfind("bISO", 0) == 0 || head.rfind("aBCR", 0) == 0 ||
      head.rfind("bBCR", 0) == 0) {
    out.grid = read_sdf(file);
    out.format = "sdf";
    return out;
  }
  const bool sur = head.rfind("DIGITAL SURF", 0) == 0 || head.rfind("DSCOMPRESSED", 0) == 0;
  if (sur || looks_like_bcr(head) || looks_like_dektak(head)) {
    std::ifstream f(file, std::ios::binary);
    std::ostringstream ss;
    ss << f.rdbuf();
    return read_bytes(ss.str(), file.string(), lower_ext(file));
  }
  if (head.find("# x0_mm=") != std::string::npos) {
    out.grid = read_height_csv(file);
    out.format = "csv";
    return out;
  }
  if (std::any_of(head.begin(), head.end(), [](char c) { return c == '\0'; }))
    throw core::Error(file.string() +
                      ": a binary file of unknown format (vmsim reads X3P, .sur, SDF, BCR-STM, CSV and ASCII grids)");
  const std::string ext = lower_ext(file);
  if (ext == ".xyz" || ext == ".asc" || ext == ".pts") {
    out.grid = read_xyz_grid(file);
    out.format = "xyz";
    return out;
  }
  out.grid = read_matrix_grid(file);
  out.format = "matrix";
  return out;
}

void write_surface(const std::filesystem::path& file, const core::HeightGrid& grid) {
  const std::string ext = lower_ext(file);
  if (ext == ".x3p")
    write_x3p(file, grid);
  else if (ext == ".sdf")
    write_sdf(file, grid);
  else if (ext == ".sur")
    write_sur(file, grid);
  else if (ext == ".csv")
    write_height_csv(file, grid);
  else if (ext == ".xyz")
    write_xyz(file, grid);
  else if (ext == ".npy")
    write_height_npy(file, grid);
  else
    throw core::Error(file.string() + ": unknown surface format (write .x3p, .sdf, .sur, .csv, .xyz or .npy)");
}

}  // namespace vmsim::metrology
