#include "metrology/surface_io.hpp"

#include "core/error.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/sdf.hpp"
#include "metrology/sur.hpp"
#include "metrology/x3p.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <string>

namespace vmsim::metrology {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

}  // namespace

SurfaceFile read_surface_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  in.close();
  SurfaceFile out;
  if (head.rfind("PK\x03\x04", 0) == 0) {
    X3pData d = read_x3p(file);
    if (d.grid.z_mm.size() == 0)
      throw core::Error(file.string() + ": the X3P point list does not lie on a regular x/y grid; vmsim compares grids");
    out.grid = std::move(d.grid);
    out.format = "x3p";
    if (!d.meta.rotation_identity) out.note = "the file's Record1/Axes/Rotation is not the identity and was not applied";
    return out;
  }
  if (head.rfind("DIGITAL SURF", 0) == 0 || head.rfind("DSCOMPRESSED", 0) == 0) {
    out.grid = read_sur(file);
    out.format = "sur";
    return out;
  }
  if (head.rfind("aISO", 0) == 0 || head.rfind("bISO", 0) == 0 || head.rfind("aBCR", 0) == 0 || head.rfind("bBCR", 0) == 0) {
    out.grid = read_sdf(file);
    out.format = "sdf";
    return out;
  }
  if (head.find("# x0_mm=") != std::string::npos) {
    out.grid = read_height_csv(file);
    out.format = "csv";
    return out;
  }
  if (std::any_of(head.begin(), head.end(), [](char c) { return c == '\0'; }))
    throw core::Error(file.string() + ": a binary file of unknown format (vmsim reads X3P, .sur, SDF, CSV and ASCII grids)");
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
  if (ext == ".x3p") write_x3p(file, grid);
  else if (ext == ".sdf") write_sdf(file, grid);
  else if (ext == ".sur") write_sur(file, grid);
  else if (ext == ".csv") write_height_csv(file, grid);
  else if (ext == ".xyz") write_xyz(file, grid);
  else if (ext == ".npy") write_height_npy(file, grid);
  else throw core::Error(file.string() + ": unknown surface format (write .x3p, .sdf, .sur, .csv, .xyz or .npy)");
}

}  // namespace vmsim::metrology
