// load_job, load_machine, read_program, canon; the Job (keys read and overridden as `vmsim study` overrides them)
// and its chain: interpolate (sim::Chain), simulate (sim::run_motion), run (sim::run_job, and the files of
// `vmsim run` through sim::write_run_outputs).
#include "core/error.hpp"
#include "core/machine.hpp"
#include "core/timing.hpp"
#include "core/toml_reader.hpp"
#include "program/gcode.hpp"
#include "program/program.hpp"
#include "program/sinumerik.hpp"
#include "python/py_job.hpp"
#include "render/mesh_io.hpp"
#include "render/report_html.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"
#include "sim/motion_run.hpp"
#include "sim/run.hpp"
#include "sim/run_outputs.hpp"
#include "sim/study.hpp"

#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <toml++/toml.h>

#include <fstream>
#include <sstream>

namespace vmsim::python {

namespace fs = std::filesystem;

namespace {

// A Python value as a TOML expression (what a study file would hold for it).
std::string to_toml(py::handle v) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::int_>(v)) return py::str(v).cast<std::string>();
  if (py::isinstance<py::float_>(v)) return py::repr(v).cast<std::string>();  // shortest round trip; inf, nan
  if (py::isinstance<py::str>(v) || py::hasattr(v, "__fspath__")) {
    const py::object s = py::module_::import("os").attr("fspath")(v);
    return py::module_::import("json").attr("dumps")(s).cast<std::string>();  // a TOML basic string
  }
  if (py::isinstance<py::dict>(v)) {
    std::string out = "{";
    for (auto [k, x] : v.cast<py::dict>()) {
      if (out.size() > 1) out += ", ";
      out += py::module_::import("json").attr("dumps")(py::str(k)).cast<std::string>() + " = " + to_toml(x);
    }
    return out + "}";
  }
  if (py::isinstance<py::sequence>(v)) {
    std::string out = "[";
    for (py::handle x : v.cast<py::sequence>()) {
      if (out.size() > 1) out += ", ";
      out += to_toml(x);
    }
    return out + "]";
  }
  // numpy scalars and other numbers
  if (py::hasattr(v, "__float__"))
    return py::repr(py::float_(py::reinterpret_borrow<py::object>(v))).cast<std::string>();
  throw core::Error("job.override: cannot write a value of type " +
                    py::str(v.get_type().attr("__name__")).cast<std::string>() +
                    " as TOML (use bool, int, float, str, a path, a list or a dict)");
}

py::object toml_to_python(const toml::node& n) {
  if (const auto* t = n.as_table()) {
    py::dict d;
    for (const auto& [k, v] : *t) d[py::str(std::string(k.str()))] = toml_to_python(v);
    return d;
  }
  if (const auto* a = n.as_array()) {
    py::list l;
    for (const auto& v : *a) l.append(toml_to_python(v));
    return l;
  }
  if (auto b = n.value_exact<bool>()) return py::bool_(*b);
  if (auto i = n.value_exact<int64_t>()) return py::int_(*i);
  if (auto d = n.value_exact<double>()) return py::float_(*d);
  if (auto s = n.value_exact<std::string>()) return py::str(*s);
  std::ostringstream os;
  n.visit([&](const auto& x) { os << x; });
  return py::str(os.str());
}

// The node at a dotted key; arrays of tables are entered by their elements' "name" (or "axis"), as study keys are.
const toml::node* find_key(const toml::node& root, const std::vector<std::string>& segs) {
  const toml::node* n = &root;
  for (const std::string& seg : segs) {
    if (const auto* t = n->as_table()) {
      n = t->get(seg);
    } else if (const auto* a = n->as_array(); a && a->is_array_of_tables()) {
      const toml::node* found = nullptr;
      for (const toml::node& el : *a) {
        const toml::table& et = *el.as_table();
        auto name = et["name"].value<std::string>();
        if (!name) name = et["axis"].value<std::string>();
        if (name && *name == seg) found = &el;
      }
      n = found;
    } else {
      return nullptr;
    }
    if (!n) return nullptr;
  }
  return n;
}

std::vector<std::string> split(const std::string& key) {
  std::vector<std::string> segs;
  std::size_t a = 0;
  for (;;) {
    const std::size_t b = key.find('.', a);
    segs.push_back(key.substr(a, b == std::string::npos ? std::string::npos : b - a));
    if (b == std::string::npos) break;
    a = b + 1;
  }
  return segs;
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  if (!out.flush()) throw core::Error(file.string() + ": cannot write the job's overridden copy");
}

}  // namespace

PyJob::PyJob(const fs::path& path) : file_(fs::absolute(path)) { reload(); }

void PyJob::reload() {
  auto loaded = std::make_shared<LoadedJob>();
  if (overrides_.empty() || (overrides_.size() == 1 && overrides_.front().key == "feed_scale")) {
    loaded->job = core::load_job(file_);
  } else {
    // The study mechanism (sim/study.hpp): the job (and machine) file with the overrides applied, every path in it
    // absolute; paths set here are resolved against the job file's directory, as a study's against the study's.
    sim::Study study;
    study.file = file_;
    study.base_job = file_;
    sim::StudyVariation v;
    v.index = 1;
    v.name = "job.override";
    for (const sim::StudyOverride& o : overrides_)
      if (o.key != "feed_scale") v.overrides.push_back(o);
    const sim::PreparedVariation p = sim::prepare_variation(study, v);
    loaded->dir = std::make_shared<TempDir>();
    const fs::path job_file = loaded->dir->path / file_.filename();
    write_text(job_file, p.job_toml);
    if (p.machine_toml) write_text(loaded->dir->path / "machine.toml", *p.machine_toml);
    try {
      loaded->job = core::load_job(job_file);
    } catch (const core::Error& e) {
      std::string keys;
      for (const sim::StudyOverride& o : v.overrides) keys += (keys.empty() ? "" : ", ") + o.key;
      throw core::Error(std::string(e.what()) + " [in " + file_.string() + " with job.override() of " + keys + "]");
    }
  }
  // As `vmsim run` does on load: a CL program's own tools when the job gives none (its stderr note is in the report's
  // tools.source), so that job.run() cuts with the tools the command line cuts with.
  sim::use_program_tool(loaded->job);
  loaded_ = std::move(loaded);
}

void PyJob::override_key(const std::string& key, py::handle value) {
  if (key.empty() || key.front() == '.' || key.back() == '.' || key.find("..") != std::string::npos)
    throw core::Error("job.override: '" + key + "' is not a dotted key (e.g. \"interpolation.tolerance_mm\")");
  sim::StudyOverride o;
  o.key = key;
  o.value_toml = to_toml(value);
  o.value_cell = py::str(value).cast<std::string>();
  o.where = "job.override('" + key + "')";
  if (key == "feed_scale") {
    const double s = py::float_(py::reinterpret_borrow<py::object>(value)).cast<double>();
    if (!(s > 0) || !std::isfinite(s)) throw core::Error("job.override: feed_scale must be a finite number > 0");
  }
  std::vector<sim::StudyOverride> before = overrides_;
  std::erase_if(overrides_, [&](const sim::StudyOverride& x) { return x.key == key; });
  overrides_.push_back(o);
  try {
    reload();
  } catch (...) {
    overrides_ = std::move(before);  // a refused override leaves the job as it was
    throw;
  }
}

void PyJob::reset() {
  overrides_.clear();
  reload();
}

double PyJob::feed_scale() const {
  for (const sim::StudyOverride& o : overrides_)
    if (o.key == "feed_scale") return std::stod(o.value_toml);
  return 1.0;
}

py::object PyJob::get(const std::string& key) const {
  if (key == "feed_scale") return py::float_(feed_scale());
  const core::Job& job = loaded_->job;
  const bool machine = key.rfind("machine.", 0) == 0;
  std::vector<std::string> segs = split(key);
  if (machine) segs.erase(segs.begin());
  const fs::path file = machine ? job.machine_file : job.file;
  const toml::table t = core::parse_toml_file(file);
  const toml::node* n = find_key(t, segs);
  if (!n)
    throw py::key_error(key + ": not set in " + (machine ? "the machine file " : "the job file ") + file.string() +
                        " (the default then applies; parts/README.md lists every key)");
  return toml_to_python(*n);
}

nlohmann::json PyJob::overrides_json() const {
  nlohmann::json j = nlohmann::json::object();
  for (const sim::StudyOverride& o : overrides_) j[o.key] = o.value_toml;
  return j;
}

void bind_job(py::module_& m) {
  bind_results(m);

  py::class_<core::Machine, std::shared_ptr<core::Machine>>(m, "Machine", R"(A machine file as vmsim reads it.

axes: a list of dicts per axis (name, kind "linear"|"rotary", travel, limits in axis units: mm or rad, per s, s^2,
s^3; drive: the cascade's parameters as the file gives them, or None).)")
      .def_readonly("name", &core::Machine::name)
      .def_readonly("file", &core::Machine::source_file)
      .def_readonly("kinematics", &core::Machine::kinematics)
      .def_property_readonly("axis_names",
                             [](const core::Machine& mc) {
                               std::vector<std::string> n;
                               for (const auto& a : mc.axes) n.push_back(a.name);
                               return n;
                             })
      .def_property_readonly("axes",
                             [](const core::Machine& mc) {
                               py::list l;
                               for (const auto& a : mc.axes) {
                                 py::dict d;
                                 d["name"] = a.name;
                                 d["kind"] = a.kind == core::AxisKind::Rotary ? "rotary" : "linear";
                                 d["travel_min"] = a.travel_min;
                                 d["travel_max"] = a.travel_max;
                                 d["continuous"] = a.continuous;
                                 d["max_velocity"] = a.max_velocity;
                                 d["max_acceleration"] = a.max_acceleration;
                                 d["max_jerk"] = a.max_jerk;
                                 d["has_drive"] = a.drive.has_value();
                                 l.append(d);
                               }
                               return l;
                             })
      .def("__repr__",
           [](const core::Machine& mc) { return "<vmsim.Machine " + mc.name + " (" + mc.source_file + ")>"; });

  m.def(
      "load_machine", [](const fs::path& p) { return std::make_shared<core::Machine>(core::load_machine(p)); },
      py::arg("path"),
      "Reads a machine file (TOML, parts/README.md). Raises vmsim.Error naming the file, line and key.");

  m.def(
      "read_program",
      [](const fs::path& path, const std::string& dialect, std::optional<fs::path> tool_table,
         std::optional<std::array<double, 3>> start_mm, bool lenient) {
        program::ProgramOptions o;
        o.dialect = program::parse_dialect(dialect);
        o.tool_table = tool_table;
        o.start_mm = start_mm;
        o.lenient = lenient;
        py::gil_scoped_release release;
        return std::make_shared<core::ToolPath>(program::read_program(path, o));
      },
      py::arg("path"), py::arg("dialect") = "auto", py::arg("tool_table") = py::none(),
      py::arg("start_mm") = py::none(), py::arg("lenient") = false,
      R"(Reads a program (RS274/NGC G-code, Sinumerik 840D, APT/CL) into a vmsim.Program: its moves in the workpiece
frame. dialect: "auto" (by extension and content) | "rs274ngc" | "sinumerik" | "apt"; tool_table: a LinuxCNC tool
table; start_mm: where the tool starts (x, y, z). Raises vmsim.Error naming the file and line.)");

  m.def(
      "canon",
      [](const fs::path& path, const std::string& dialect, std::optional<fs::path> tool_table, bool lenient) {
        const program::Dialect d = program::program_dialect(path, program::parse_dialect(dialect));
        if (d == program::Dialect::Apt)
          throw core::Error(path.string() + ": vmsim canon reads G-code and Sinumerik programs, not APT CL files");
        std::vector<program::CanonCall> calls;
        if (d == program::Dialect::Sinumerik) {
          program::SinumerikOptions o;
          o.lenient = lenient;
          calls = program::interpret_sinumerik(path, o).canon;
        } else {
          program::GcodeOptions o;
          o.tool_table = tool_table;
          calls = program::interpret_gcode(path, o).canon;
        }
        std::vector<std::string> lines;
        int number = 0;
        for (const program::CanonCall& c : calls) lines.push_back(program::format_canon_line(++number, c));
        return lines;
      },
      py::arg("path"), py::arg("dialect") = "auto", py::arg("tool_table") = py::none(), py::arg("lenient") = false,
      "LinuxCNC's canonical machining calls for a G-code (or Sinumerik) program, one string per call, as `vmsim canon` "
      "and `rs274 -g` print them.");

  py::class_<PyJob, std::shared_ptr<PyJob>>(m, "Job", R"(A job file (job.toml) as vmsim runs it.

Keys are read with job.get("interpolation.tolerance_mm") or job["..."] and overridden with
job.override("machine.axes.X.drive.kv_1000_per_min", 6), exactly as a `vmsim study` variation overrides them
(keys under "machine." change the job's machine file; "feed_scale" multiplies every programmed feed). An override
is checked at once: a refused one raises vmsim.Error and leaves the job as it was.)")
      .def_property_readonly("name", [](const PyJob& j) { return j.job().name; })
      .def_property_readonly(
          "file", [](const PyJob& j) { return j.file(); }, "the job file as loaded (overrides apply to a copy)")
      .def_property_readonly("machine_file", [](const PyJob& j) { return j.job().machine_file; })
      .def_property_readonly("program_file", [](const PyJob& j) { return j.job().program_file; })
      .def_property_readonly("feed_scale", &PyJob::feed_scale)
      .def_property_readonly(
          "overrides", [](const PyJob& j) { return to_python(j.overrides_json()); },
          "{key: value as TOML text} of every override in force")
      .def_property_readonly("machine", [](const PyJob& j) { return std::make_shared<core::Machine>(j.job().machine); })
      .def("get", &PyJob::get, py::arg("key"),
           "The value of a dotted key in the job file (\"machine.\" keys: in its machine file), with the overrides; "
           "KeyError when the file does not set it.")
      .def("__getitem__", &PyJob::get)
      .def("override", &PyJob::override_key, py::arg("key"), py::arg("value"),
           "Sets a key as a study variation does (bool, int, float, str or path, list, dict); raises vmsim.Error "
           "naming the key when the job no longer loads.")
      .def("__setitem__", &PyJob::override_key)
      .def("reset", &PyJob::reset, "Drops every override.")
      .def(
          "program", [](const PyJob& j) { return std::make_shared<core::ToolPath>(sim::read_job_program(j.job())); },
          "The job's program as the chain reads it (the job's tool table, start and dialect), a vmsim.Program.")
      .def(
          "interpolate", &interpolate_job, py::arg("progress") = py::none(),
          (std::string("Runs the job's interpolator (sim::Chain: period, tolerance, feed plan, feed_scale) and returns "
                       "its vmsim.Setpoints.\n") +
           kProgressDoc)
              .c_str())
      .def(
          "simulate", &simulate_job, py::arg("full_rate_trace") = false, py::arg("progress") = py::none(),
          (std::string("Runs the job's motion as `vmsim motion` does (interpolator, drives, contour error) and returns "
                       "a vmsim.Motion. full_rate_trace: also every current-loop sample (large).\n") +
           kProgressDoc)
              .c_str())
      .def("run", &run_job, py::arg("out") = py::none(), py::arg("render") = false, py::arg("progress") = py::none(),
           (std::string("Runs the whole chain as `vmsim run` does and returns a vmsim.Result. out: a directory to "
                        "write the files `vmsim run --no-render` writes (the same writer; report.json and "
                        "report.html). render=True is not available from Python yet (the pictures' code lives in "
                        "the command line).\n") +
            kProgressDoc)
               .c_str())
      .def("__repr__", [](const PyJob& j) {
        return "<vmsim.Job " + j.job().name + " (" + j.file().string() + ")" +
               (j.overrides_json().empty() ? std::string() : " with " + j.overrides_json().dump()) + ">";
      });

  m.def(
      "load_job", [](const fs::path& p) { return std::make_shared<PyJob>(p); }, py::arg("path"),
      "Reads a job file (job.toml, parts/README.md) and its machine file. Raises vmsim.Error naming the file, line "
      "and key.");
}

}  // namespace vmsim::python
