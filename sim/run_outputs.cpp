#include "sim/run_outputs.hpp"

#include "core/atomic_file.hpp"
#include "core/stl.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/x3p.hpp"
#include "sim/report.hpp"
#include "sim/signals.hpp"

#include <fmt/format.h>

namespace vmsim::sim {

namespace {

namespace fs = std::filesystem;

// The N-buffer's results: one line per needle (nominal point and normal, offsets, deviation).
void write_needles_csv(const fs::path& file, const RunResult& r) {
  core::AtomicFile out(file);
  out.stream() << "x_mm,y_mm,z_mm,nx,ny,nz,surface_offset_mm,reference_offset_mm,deviation_mm\n";
  const Field& field = r.cut.field;
  for (std::size_t k = 0; k < field.needles.size(); ++k) {
    const auto kk = static_cast<Eigen::Index>(k);
    const Eigen::Vector3d& p = field.needle_point[k];
    const Eigen::Vector3d& n = field.needle_normal[k];
    out.stream() << fmt::format("{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.7f},{:.7f},{:.7f}\n", p.x(), p.y(), p.z(),
                                n.x(), n.y(), n.z(), r.needle_offset_mm[kk], r.needle_reference_mm[kk],
                                r.needle_deviation_mm[kk]);
  }
  out.commit();
}

}  // namespace

std::vector<std::string> write_run_outputs(const core::Job& job, const RunResult& r, const fs::path& dir,
                                           const VtpWriter& write_vtp) {
  std::vector<std::string> files;
  auto write_mesh = [&](const core::TriangleMesh& mesh) {
    core::write_stl_binary(dir / "part.stl", mesh);
    write_vtp(dir / "part.vtp", mesh);
    files.insert(files.end(), {"part.stl", "part.vtp"});
  };
  if (r.surface) {
    metrology::write_height_csv(dir / "surface.csv", *r.surface);
    metrology::write_height_npy(dir / "surface.npy", *r.surface);
    files.insert(files.end(), {"surface.csv", "surface.npy", "surface.npy.json"});
    // X3P (ISO 5436-2) for metrology tools: MountainsMap, Gwyddion, vmsim compare.
    metrology::X3pWriteOptions x3p;
    x3p.version = std::string("vmsim ") + version();
    x3p.comment = "predicted surface of job " + job.name;
    metrology::write_x3p(dir / "surface.x3p", *r.surface, x3p);
    files.push_back("surface.x3p");
    if (r.deviation) {
      metrology::write_height_csv(dir / "reference.csv", *r.reference_surface);
      metrology::write_height_csv(dir / "deviation.csv", *r.deviation);
      metrology::write_height_npy(dir / "deviation.npy", *r.deviation);
      files.insert(files.end(), {"reference.csv", "deviation.csv", "deviation.npy", "deviation.npy.json"});
      // deviation.* is along the reference's normal; the vertical height difference beside it.
      metrology::write_height_npy(dir / "deviation_vertical.npy", *r.deviation_vertical);
      files.insert(files.end(), {"deviation_vertical.npy", "deviation_vertical.npy.json"});
      x3p.comment = "reference surface of job " + job.name + " (" + r.cut.reference.name + ")";
      metrology::write_x3p(dir / "reference.x3p", *r.reference_surface, x3p);
      x3p.comment =
          "deviation of job " + job.name + ": predicted - reference along the reference's normal (negative: overcut)";
      metrology::write_x3p(dir / "deviation.x3p", *r.deviation, x3p);
      files.insert(files.end(), {"reference.x3p", "deviation.x3p"});
    }
  } else {
    write_needles_csv(dir / "needles.csv", r);
    files.push_back("needles.csv");
  }
  if (r.part_mesh) write_mesh(*r.part_mesh);
  if (r.level_set) {
    write_mesh(r.level_set->mesh);
    r.level_set->part.write_vdb(dir / "part.vdb");
    files.push_back("part.vdb");
  }
  if (r.signals) {
    write_signals(dir / "signals.csv", *r.signals);
    files.push_back("signals.csv");
  }
  return files;
}

}  // namespace vmsim::sim
