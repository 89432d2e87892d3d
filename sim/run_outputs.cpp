#include "sim/run_outputs.hpp"
#include "sim/tools.hpp"

#include "core/atomic_file.hpp"
#include "core/stl.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/x3p.hpp"
#include "sim/part_mesh.hpp"
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
                                           const VtpWriter& write_vtp, nlohmann::json* report) {
  const core::OutputsSpec& o = job.outputs;
  std::vector<std::string> files;
  nlohmann::json info = nlohmann::json::object();
  std::vector<std::string> notes;
  auto write_mesh = [&](const core::TriangleMesh& mesh) {
    core::write_stl_binary(dir / "part.stl", mesh);
    write_vtp(dir / "part.vtp", mesh, o.vtp_compression_level);
    files.insert(files.end(), {"part.stl", "part.vtp"});
  };
  const double nodes = r.surface ? static_cast<double>(r.surface->nx()) * static_cast<double>(r.surface->ny()) : 0.0;
  const bool large = nodes > o.large_grid_nodes;
  if (r.surface) {
    const bool csv = o.csv == core::OutputsSpec::Csv::Always || (o.csv == core::OutputsSpec::Csv::Auto && !large);
    info["csv"] = csv;
    if (!csv && o.csv == core::OutputsSpec::Csv::Auto)
      notes.push_back(fmt::format(
          "the CSV grids (surface.csv, reference.csv, deviation.csv) are not written: the grid has {:.0f} nodes, more "
          "than [outputs] large_grid_nodes = {:.0f} (the same heights are in the .npy and .x3p files; [outputs] csv = "
          "\"always\" writes them)",
          nodes, o.large_grid_nodes));
    if (csv) {
      metrology::write_height_csv(dir / "surface.csv", *r.surface);
      files.push_back("surface.csv");
    }
    if (o.npy) {
      metrology::write_height_npy(dir / "surface.npy", *r.surface);
      files.insert(files.end(), {"surface.npy", "surface.npy.json"});
    }
    // A job with several tools: which tool last cut each node (1 byte per node), the data of images/tools.png, so
    // that vmsim render redraws it and Python reads it (numpy.load).
    if (const auto& m = r.cut.tool_map; m && m->nu == r.surface->nx() && m->nv == r.surface->ny()) {
      metrology::write_index_npy(dir / "tool_map.npy", tool_index(*m), *r.surface,
                                 "index into report.json tools.list of the tool that last cut the node; -1: uncut");
      files.insert(files.end(), {"tool_map.npy", "tool_map.npy.json"});
    }
    // X3P (ISO 5436-2) for metrology tools: MountainsMap, Gwyddion, vmsim compare.
    metrology::X3pWriteOptions x3p;
    x3p.version = std::string("vmsim ") + version();
    x3p.comment = "predicted surface of job " + job.name;
    if (o.x3p) {
      metrology::write_x3p(dir / "surface.x3p", *r.surface, x3p);
      files.push_back("surface.x3p");
    }
    if (r.deviation) {
      if (csv) {
        metrology::write_height_csv(dir / "reference.csv", *r.reference_surface);
        metrology::write_height_csv(dir / "deviation.csv", *r.deviation);
        files.insert(files.end(), {"reference.csv", "deviation.csv"});
      }
      if (o.npy) {
        metrology::write_height_npy(dir / "deviation.npy", *r.deviation);
        files.insert(files.end(), {"deviation.npy", "deviation.npy.json"});
        // deviation.* is along the reference's normal; the vertical height difference beside it.
        metrology::write_height_npy(dir / "deviation_vertical.npy", *r.deviation_vertical);
        files.insert(files.end(), {"deviation_vertical.npy", "deviation_vertical.npy.json"});
      }
      if (o.x3p) {
        x3p.comment = "reference surface of job " + job.name + " (" + r.cut.reference.name + ")";
        metrology::write_x3p(dir / "reference.x3p", *r.reference_surface, x3p);
        x3p.comment =
            "deviation of job " + job.name + ": predicted - reference along the reference's normal (negative: overcut)";
        metrology::write_x3p(dir / "deviation.x3p", *r.deviation, x3p);
        files.insert(files.end(), {"reference.x3p", "deviation.x3p"});
      }
    }
  } else {
    write_needles_csv(dir / "needles.csv", r);
    files.push_back("needles.csv");
  }
  using Mesh = core::OutputsSpec::Mesh;
  if (r.part_mesh_triangles >= 0) {
    // A large grid's mesh is left out by default: the height field is in the .npy and .x3p files, and on a
    // scalloped part few blocks are flat (flower_mold at 0.025 mm: 18 %, the mesh 13 % smaller; bench/README.md).
    const Mesh mode = o.part_mesh == Mesh::Auto ? (large ? Mesh::None : Mesh::Full) : o.part_mesh;
    if (mode == Mesh::Full) {
      write_mesh(grid_part_mesh(r));
      info["part_mesh"] = {{"kind", "full"}, {"triangles", r.part_mesh_triangles}};
    } else if (mode == Mesh::Simplified) {
      const SimplifiedMesh s = simplified_heightfield_mesh(*r.surface, r.cut.field.region.lo.z(),
                                                           r.deviation ? &*r.deviation : nullptr, o.mesh_tolerance_mm);
      write_mesh(s.mesh);
      info["part_mesh"] = {{"kind", "simplified"},
                           {"triangles", s.mesh.triangles.rows()},
                           {"full_triangles", r.part_mesh_triangles},
                           {"tolerance_mm", o.mesh_tolerance_mm},
                           {"error_bound_mm", s.error_bound_mm},
                           {"flat_blocks", s.flat_blocks},
                           {"blocks", s.blocks}};
    } else {
      info["part_mesh"] = {{"kind", "none"}};
      if (o.part_mesh == Mesh::Auto)
        notes.push_back(fmt::format(
            "part.stl and part.vtp are not written: the grid has {:.0f} nodes, more than [outputs] large_grid_nodes "
            "= {:.0f} (the height field is in the .npy and .x3p files; [outputs] part_mesh = \"full\" writes the "
            "mesh of {} triangles, \"simplified\" merges its flat blocks within 2 x mesh_tolerance_mm)",
            nodes, o.large_grid_nodes, r.part_mesh_triangles));
    }
  }
  if (r.level_set) {
    if (o.part_mesh != Mesh::None) write_mesh(r.level_set->mesh);
    info["part_mesh"] = {{"kind", o.part_mesh == Mesh::None ? "none" : "level set"}};
    r.level_set->part.write_vdb(dir / "part.vdb");
    files.push_back("part.vdb");
  }
  if (r.signals) {
    write_signals(dir / "signals.csv", *r.signals);
    files.push_back("signals.csv");
  }
  if (!notes.empty()) info["notes"] = notes;
  if (report) (*report)["outputs"] = info;
  return files;
}

}  // namespace vmsim::sim
