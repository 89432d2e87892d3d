// Metrology from Python: read any surface file vmsim reads, write X3P, ISO 25178-2 areal parameters after form
// removal and Gaussian filters (as `vmsim stats`), and a measured scan held against a prediction (as `vmsim compare`).
#include "core/error.hpp"
#include "metrology/compare.hpp"
#include "metrology/processing.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"
#include "python/py_types.hpp"

#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>

namespace vmsim::python {

namespace fs = std::filesystem;

namespace {

py::object num(double v) { return std::isfinite(v) ? py::object(py::float_(v)) : py::object(py::none()); }

// The keys `vmsim stats` prints under "areal" (app/cmd_surface.cpp areal_json); NaN (Ssk, Sku of a flat surface) as
// None.
py::dict areal_dict(const metrology::ArealParameters& p) {
  py::dict d;
  d["points"] = p.points;
  d["mean_mm"] = num(p.mean_mm);
  d["Sa_mm"] = num(p.Sa_mm);
  d["Sq_mm"] = num(p.Sq_mm);
  d["Sp_mm"] = num(p.Sp_mm);
  d["Sv_mm"] = num(p.Sv_mm);
  d["Sz_mm"] = num(p.Sz_mm);
  d["Ssk"] = num(p.Ssk);
  d["Sku"] = num(p.Sku);
  d["Sdq"] = num(p.Sdq);
  d["Sdr_percent"] = num(p.Sdr_percent);
  return d;
}

// level: "none" | "plane" | "poly:N" | 0 | 1 | N; filters: [("L", 0.8), ("S", 0.0025)] or ["L0.8", ...] (mm).
metrology::SurfaceProcessing processing_of(py::handle level, py::handle filters) {
  metrology::SurfaceProcessing how;
  if (py::isinstance<py::str>(level)) {
    const std::string s = level.cast<std::string>();
    if (s == "none")
      how.level = 0;
    else if (s == "plane")
      how.level = 1;
    else if (s.rfind("poly:", 0) == 0)
      how.level = std::stoi(s.substr(5));
    else
      throw core::Error("level: expected \"none\", \"plane\", \"poly:N\" or an integer degree, found \"" + s + "\"");
  } else {
    how.level = level.cast<int>();
  }
  if (how.level < 0 || how.level > 12) throw core::Error("level: the form's degree must be 0..12");
  if (!filters.is_none()) {
    for (py::handle f : filters.cast<py::sequence>()) {
      metrology::SurfaceFilter sf;
      std::string kind;
      if (py::isinstance<py::str>(f)) {
        const std::string s = f.cast<std::string>();
        kind = s.substr(0, 1);
        try {
          sf.cutoff_mm = std::stod(s.substr(1));
        } catch (const std::exception&) {
          throw core::Error("filters: expected \"L0.8\" or \"S0.0025\" (kind, then the cut-off in mm), found \"" + s +
                            "\"");
        }
      } else {
        const py::sequence t = f.cast<py::sequence>();
        if (t.size() != 2) throw core::Error("filters: each filter is (kind, cutoff_mm), e.g. (\"L\", 0.8)");
        kind = t[0].cast<std::string>();
        sf.cutoff_mm = t[1].cast<double>();
      }
      if (kind != "L" && kind != "S")
        throw core::Error("filters: kind must be \"L\" (high-pass) or \"S\" (low-pass), found \"" + kind + "\"");
      if (!(sf.cutoff_mm > 0) || !std::isfinite(sf.cutoff_mm)) throw core::Error("filters: the cut-off must be > 0 mm");
      sf.kind = kind[0];
      how.filters.push_back(sf);
    }
  }
  return how;
}

core::HeightGrid grid_arg(py::handle g, const char* what) {
  if (py::isinstance<core::HeightGrid>(g)) return g.cast<const core::HeightGrid&>();
  if (py::isinstance<py::str>(g) || py::hasattr(g, "__fspath__")) {
    const fs::path p = py::module_::import("os").attr("fspath")(g).cast<std::string>();
    py::gil_scoped_release release;
    return metrology::read_surface(p);
  }
  throw core::Error(std::string(what) + ": expected a vmsim.Grid or a surface file's path");
}

py::dict stats_dict(const metrology::DeviationStats& s) {
  py::dict d;
  d["points"] = s.points;
  d["min_mm"] = num(s.min);
  d["max_mm"] = num(s.max);
  d["mean_mm"] = num(s.mean);
  d["rms_mm"] = num(s.rms);
  d["mean_abs_mm"] = num(s.mean_abs);
  return d;
}

py::list marks_list(const std::vector<metrology::Mark>& marks) {
  py::list l;
  for (const metrology::Mark& m : marks) {
    py::dict d;
    d["depth_mm"] = m.depth_mm;
    d["kind"] = m.overcut ? "overcut" : "undercut";
    d["x_mm"] = m.x_mm;
    d["y_mm"] = m.y_mm;
    d["x_extent_mm"] = m.x_extent_mm;
    d["y_extent_mm"] = m.y_extent_mm;
    d["area_mm2"] = m.area_mm2;
    d["along_mm"] = m.along_mm;
    d["width_mm"] = m.width_mm;
    d["direction_rad"] = num(m.direction_rad);
    l.append(d);
  }
  return l;
}

}  // namespace

void bind_metrology(py::module_& m) {
  m.def(
      "read_surface",
      [](const fs::path& p) {
        metrology::SurfaceFile f;
        {
          py::gil_scoped_release release;
          f = metrology::read_surface_file(p);
        }
        auto g = std::make_shared<core::HeightGrid>(std::move(f.grid));
        py::object o = py::cast(g);
        o.attr("format") = f.format;  // "x3p", "sur", "sdf", "bcr", "dektak", "csv", "xyz", "matrix" (+"+gzip")
        o.attr("note") = f.note;
        return o;
      },
      py::arg("path"),
      R"(Reads any surface file vmsim reads, recognised by its content: X3P, Digital Surf .sur, SDF, BCR-STM, Dektak CSV
(a profile, as one row), vmsim's matrix CSV, .xyz and other x y z or matrix text, gzip-compressed or not. Returns a
vmsim.Grid (invalid points NaN, mask False) with .format and .note (what the reader wants you to know).)");

  m.def(
      "write_surface",
      [](const fs::path& p, const core::HeightGrid& g) {
        py::gil_scoped_release release;
        metrology::write_surface(p, g);
      },
      py::arg("path"), py::arg("grid"),
      "Writes a grid by the file's extension: .x3p, .sdf, .sur, .csv, .xyz, .npy (atomically).");

  m.def(
      "write_x3p",
      [](const fs::path& p, const core::HeightGrid& g, const std::string& comment, const std::string& date,
         int compression_level) {
        metrology::X3pWriteOptions o;
        o.comment = comment;
        o.date = date;
        o.compression_level = compression_level;
        py::gil_scoped_release release;
        metrology::write_x3p(p, g, o);
      },
      py::arg("path"), py::arg("grid"), py::arg("comment") = "", py::arg("date") = "", py::arg("compression_level") = 0,
      "Writes an ISO 5436-2 X3P file (atomically): heights in m as ISO 25178-72 asks, invalid points in the validity "
      "mask. date: xsd:dateTime, empty for now (UTC); compression_level 0 (stored) .. 9.");

  m.def(
      "areal",
      [](py::object grid, py::object level, py::object filters, double outlier_sigma) {
        const metrology::SurfaceProcessing how = processing_of(level, filters);
        core::HeightGrid g = grid_arg(grid, "areal");
        metrology::SurfaceAnalysis a;
        {
          py::gil_scoped_release release;
          a = metrology::analyse_surface(std::move(g), how, outlier_sigma);
        }
        py::dict d = areal_dict(a.areal);
        if (a.form) {
          d["form_slope_x"] = a.form->slope_x;
          d["form_slope_y"] = a.form->slope_y;
          d["form_rms_residual_mm"] = a.form->rms_residual_mm;
        }
        if (a.outliers) d["outliers_masked"] = a.outliers->masked;
        return d;
      },
      py::arg("grid"), py::arg("level") = "plane", py::arg("filters") = py::none(), py::arg("outlier_sigma") = 0.0,
      R"(ISO 25178-2 areal parameters of a grid (or a surface file), as `vmsim stats` computes them: spikes masked when
outlier_sigma > 0, the form removed (level: "none", "plane", "poly:N" or the degree), then Gaussian filters in order
(filters: [("L", 0.8)] high-pass keeps the roughness, ("S", cutoff) low-pass; or strings "L0.8"). Returns a dict:
points, mean_mm, Sa_mm, Sq_mm, Sp_mm, Sv_mm, Sz_mm, Ssk, Sku, Sdq, Sdr_percent (None where undefined).)");

  m.def(
      "compare",
      [](py::object measured, py::object predicted, bool align, double outlier_sigma, double mark_threshold_mm,
         std::optional<double> path_direction_rad, py::object level, py::object filters) {
        metrology::SurfaceCompareOptions o;
        o.align = align;
        o.outlier_sigma = outlier_sigma;
        o.mark_threshold_mm = mark_threshold_mm;
        o.path_direction_rad = path_direction_rad;
        o.processing = processing_of(level, filters);
        core::HeightGrid scan = grid_arg(measured, "compare: measured");
        metrology::Prediction pred{grid_arg(predicted, "compare: predicted"), std::nullopt};
        std::shared_ptr<metrology::SurfaceComparison> c;
        {
          py::gil_scoped_release release;
          c = std::make_shared<metrology::SurfaceComparison>(metrology::compare_surfaces(std::move(scan), pred, o));
        }
        py::dict d;
        d["deviation"] = std::make_shared<core::HeightGrid>(std::move(c->deviation));
        d["measured_on"] = std::make_shared<core::HeightGrid>(std::move(c->measured_on));
        d["stats"] = stats_dict(c->stats);
        d["marks"] = marks_list(c->marks);
        Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
        t.topLeftCorner<3, 3>() = c->transform.R;
        t.topRightCorner<3, 1>() = c->transform.t;
        d["transform"] = t;
        if (c->registration) {
          py::dict r;
          r["rms_mm"] = c->registration->rms_mm;
          r["points"] = c->registration->points;
          r["inliers"] = c->registration->inliers;
          r["iterations"] = c->registration->iterations;
          r["converged"] = c->registration->converged;
          r["weak_directions"] = c->registration->weak_directions;
          d["registration"] = r;
        }
        if (c->outliers) d["outliers_masked"] = c->outliers->masked;
        d["path_direction_rad"] = c->path_direction_rad;
        d["measured_areal"] = areal_dict(c->measured_areal);
        d["predicted_areal"] = areal_dict(c->predicted_areal);
        return d;
      },
      py::arg("measured"), py::arg("predicted"), py::arg("align") = true, py::arg("outlier_sigma") = 6.0,
      py::arg("mark_threshold_mm") = 1e-3, py::arg("path_direction_rad") = py::none(), py::arg("level") = "plane",
      py::arg("filters") = py::none(),
      R"(A measured scan held against a predicted surface, as `vmsim compare` does: spikes masked, robust 6-DoF
registration (align=False: as it lies), resampled onto the prediction's grid; then the deviation (measured -
predicted, vertical; negative: overcut) and its statistics, the marks, and the areal parameters of both on their
common area after level/filters. measured, predicted: vmsim.Grid or a surface file's path. Returns a dict:
deviation, measured_on (Grid), stats, marks, transform (4x4, scan -> prediction frame), registration,
measured_areal, predicted_areal.)");
}

}  // namespace vmsim::python
