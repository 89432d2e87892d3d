#include "core/job.hpp"
#include "core/utf8.hpp"

#include "core/error.hpp"
#include "core/toml_reader.hpp"

#include <fmt/format.h>

#include <cmath>

namespace vmsim::core {

namespace {

// The keys [tool] and [[tools]] share; the caller reads its own and finishes the table.
ToolSpec read_tool(const TomlTable& t) {
  ToolSpec tool;
  // "bull" is the short name issue 24 used; both mean the same torus-ended tool.
  const std::string type = t.choice("type", {"ball", "flat", "bullnose", "bull"});
  tool.diameter_mm = t.positive("diameter_mm");
  if (type == "ball") {
    tool.shape = ToolShape::Ball;
    tool.corner_radius_mm = tool.diameter_mm / 2;
  } else if (type == "flat") {
    tool.shape = ToolShape::Flat;
    tool.corner_radius_mm = 0.0;
  } else {
    tool.shape = ToolShape::BullNose;
    tool.corner_radius_mm = t.positive("corner_radius_mm");
    if (tool.corner_radius_mm >= tool.diameter_mm / 2)
      t.fail("corner_radius_mm",
             fmt::format("expected less than the radius {} mm (use type = \"ball\")", tool.diameter_mm / 2));
  }
  tool.flute_length_mm = t.opt_positive("flute_length_mm").value_or(2 * tool.diameter_mm);
  tool.length_mm = t.opt_positive("length_mm").value_or(std::max(50.0, tool.flute_length_mm));
  if (tool.length_mm < tool.flute_length_mm) t.fail("length_mm", "expected at least flute_length_mm");
  return tool;
}

// [[tools]]: each with its T number (or, for 840D programs' T="name", its name), no number or name twice.
std::vector<ToolSpec> read_tools(const TomlTable& top) {
  std::vector<ToolSpec> tools;
  for (const TomlTable& t : top.array_of_tables("tools")) {
    ToolSpec tool = read_tool(t);
    const std::optional<long long> n = t.opt_integer("number");
    tool.name = t.opt_string("name").value_or("");
    if (!n && tool.name.empty())
      t.fail("number", "missing (expected the program's T number, or a name for an 840D program's T=\"name\")");
    if (n && (*n < 0 || *n > 1000000000)) t.fail("number", fmt::format("expected a T number 0 or more, found {}", *n));
    tool.number = n ? static_cast<int>(*n) : -1;  // -1: by name only
    for (const ToolSpec& o : tools) {
      if (n && o.number == tool.number) t.fail("number", fmt::format("T{} is described twice", tool.number));
      if (!tool.name.empty() && o.name == tool.name) t.fail("name", "\"" + tool.name + "\" is described twice");
    }
    t.finish();
    tools.push_back(tool);
  }
  return tools;
}

StockSpec read_stock(const TomlTable& t) {
  StockSpec s;
  const std::string type = t.choice("type", {"box", "stl", "job"});
  if (type == "job") {
    s.kind = StockSpec::Kind::Job;
    s.job_file = t.existing_path("job");
  } else if (type == "box") {
    s.kind = StockSpec::Kind::Box;
    auto lo = t.numbers("min_mm", 3), hi = t.numbers("max_mm", 3);
    s.min_mm = Eigen::Vector3d(lo[0], lo[1], lo[2]);
    s.max_mm = Eigen::Vector3d(hi[0], hi[1], hi[2]);
    if (!(s.min_mm.array() < s.max_mm.array()).all()) t.fail("max_mm", "expected max_mm > min_mm on every axis");
  } else {
    s.kind = StockSpec::Kind::Mesh;
    s.mesh_file = t.existing_path("file");
  }
  t.finish();
  return s;
}

RemovalSpec read_removal(const TomlTable& t) {
  RemovalSpec r;
  const std::string field = t.opt_choice("field", {"zmap", "tridexel", "nbuffer"}).value_or("zmap");
  r.field = field == "zmap"       ? RemovalSpec::Field::ZMap
            : field == "tridexel" ? RemovalSpec::Field::TriDexel
                                  : RemovalSpec::Field::NBuffer;
  if (auto h = t.opt_positive("spacing_mm")) {
    if (*h < 1e-4) t.fail("spacing_mm", "expected at least 0.0001 mm");
    r.spacing_mm = *h;
  }
  const std::string motion = t.opt_choice("motion", {"actual", "setpoints", "program"}).value_or("actual");
  r.motion = motion == "actual"      ? RemovalSpec::Motion::Actual
             : motion == "setpoints" ? RemovalSpec::Motion::Setpoints
                                     : RemovalSpec::Motion::Program;
  if (auto tol = t.opt_positive("track_tolerance_mm")) r.track_tolerance_mm = *tol, r.track_tolerance_given = true;
  const std::string method = t.opt_choice("method", {"dexel", "vdb"}).value_or("dexel");
  r.method = method == "vdb" ? RemovalSpec::Method::Vdb : RemovalSpec::Method::Dexel;
  r.voxel_mm = r.spacing_mm;
  if (r.method == RemovalSpec::Method::Vdb) {
    if (auto h = t.opt_positive("voxel_mm")) {
      if (*h < 1e-3) t.fail("voxel_mm", "expected at least 0.001 mm");
      r.voxel_mm = *h;
    }
  } else if (t.has("voxel_mm")) {
    t.fail("voxel_mm", "only valid with method = \"vdb\"");
  }
  // The part mesh of a level set: method "vdb", or a tri-dexel field (meshed through its level set).
  if (r.method == RemovalSpec::Method::Vdb || r.field == RemovalSpec::Field::TriDexel) {
    if (auto a = t.opt_nonnegative("mesh_adaptivity")) {
      if (*a > 1) t.fail("mesh_adaptivity", "expected a number in [0, 1]");
      r.mesh_adaptivity = *a;
    }
  } else if (t.has("mesh_adaptivity")) {
    t.fail("mesh_adaptivity", "only valid with method = \"vdb\" or field = \"tridexel\"");
  }
  if (r.field == RemovalSpec::Field::NBuffer) {
    r.needles_file = t.existing_path("needles_file");
    r.needle_half_length_mm = t.opt_positive("needle_half_length_mm").value_or(1.0);
  } else if (t.has("needles_file") || t.has("needle_half_length_mm")) {
    t.fail(t.has("needles_file") ? "needles_file" : "needle_half_length_mm", "only valid with field = \"nbuffer\"");
  }
  t.finish();
  return r;
}

ReferenceSpec read_reference(const TomlTable& t) {
  ReferenceSpec r;
  const std::string kind = t.opt_choice("kind", {"program", "feed", "job", "stock", "none"}).value_or("program");
  r.kind = kind == "program" ? ReferenceSpec::Kind::Program
           : kind == "feed"  ? ReferenceSpec::Kind::Feed
           : kind == "job"   ? ReferenceSpec::Kind::Job
           : kind == "stock" ? ReferenceSpec::Kind::Stock
                             : ReferenceSpec::Kind::None;
  if (r.kind == ReferenceSpec::Kind::Job)
    r.job_file = t.existing_path("job");
  else if (t.has("job"))
    t.fail("job", "only valid with kind = \"job\"");
  if (r.kind == ReferenceSpec::Kind::Feed) {
    r.feed_scale = t.positive("feed_scale");
  } else if (t.has("feed_scale")) {
    t.fail("feed_scale", "only valid with kind = \"feed\"");
  }
  t.finish();
  return r;
}

InterpSpec read_interp(const TomlTable& t) {
  InterpSpec spec;
  if (auto te = t.opt_positive("period_ms")) {
    if (*te > 100) t.fail("period_ms", fmt::format("{} ms is not an NC interpolation period (expected <= 100)", *te));
    spec.period_s = *te * 1e-3;
  }
  if (auto tol = t.opt_positive("tolerance_mm")) spec.tolerance_mm = *tol, spec.tolerance_given = true;
  if (auto n = t.opt_positive("max_setpoints")) {
    if (*n < 2) t.fail("max_setpoints", "expected at least 2");
    spec.max_setpoints = *n;
  }
  t.finish();
  return spec;
}

FeedPlanSpec read_feedplan(const TomlTable& t) {
  FeedPlanSpec f;
  if (auto v = t.opt_positive("chord_error_um")) f.chord_error_mm = *v * 1e-3;
  if (auto v = t.opt_positive("contour_error_um")) f.contour_error_mm = *v * 1e-3;
  f.max_feed_mm_per_s = t.opt_positive("max_feed_mm_per_s");
  if (auto v = t.opt_positive("sample_spacing_mm")) f.sample_spacing_mm = *v;
  if (auto v = t.opt_integer("window_samples")) {
    if (*v < 100 || *v > 10000000) t.fail("window_samples", "expected 100 .. 10000000");
    f.window_samples = static_cast<int>(*v);
  }
  f.jerk = t.opt_boolean("jerk").value_or(true);
  f.verify = t.opt_boolean("verify").value_or(true);
  if (auto n = t.opt_table("nurbs")) {
    FeedPlanSpec::Nurbs c;
    if (auto d = n->opt_integer("degree")) {
      if (*d < 1 || *d > 9) n->fail("degree", "expected 1 .. 9");
      c.degree = static_cast<int>(*d);
    }
    c.control_points = n->existing_path("control_points");
    c.knots = n->existing_path("knots");
    n->finish();
    f.nurbs = c;
  }
  const std::string servo = t.opt_choice("servo", {"machine", "pid", "transfer_function"}).value_or("machine");
  f.servo = servo == "machine" ? FeedPlanSpec::Servo::Machine
            : servo == "pid"   ? FeedPlanSpec::Servo::Pid
                               : FeedPlanSpec::Servo::TransferFunction;
  for (const TomlTable& a : t.array_of_tables("axis")) {
    FeedPlanSpec::Axis ax;
    ax.name = a.choice("name", {"X", "Y", "Z"});
    for (const auto& other : f.axes)
      if (other.name == ax.name) a.fail("name", "axis " + ax.name + " is given twice");
    if (f.servo == FeedPlanSpec::Servo::Pid) {
      ax.kp = a.positive("kp"), ax.ki = a.positive("ki"), ax.kd = a.positive("kd");
      ax.ka = a.positive("ka"), ax.kt = a.positive("kt"), ax.inertia = a.positive("inertia_kg_m2");
      ax.damping = a.opt_nonnegative("damping").value_or(0.0), ax.rg = a.positive("rg_mm_per_rad");
    } else if (f.servo == FeedPlanSpec::Servo::TransferFunction) {
      ax.num = a.numbers("num"), ax.den = a.numbers("den");
      if (ax.den.size() < 2 || ax.den.front() == 0.0 || ax.num.empty() || ax.num.size() > ax.den.size())
        a.fail("den",
               "expected a proper transfer function: den of degree >= 1 with a non-zero first coefficient, "
               "num no longer than den");
    } else {
      a.fail("name",
             "[[feedplan.axis]] is for servo = \"pid\" or \"transfer_function\" (\"machine\" takes the "
             "machine file's drives)");
    }
    a.finish();
    f.axes.push_back(ax);
  }
  if (f.servo != FeedPlanSpec::Servo::Machine && f.axes.empty())
    t.fail("axis", "servo = \"" + servo + "\" needs a [[feedplan.axis]] table per moving axis");
  t.finish();
  return f;
}

OutputsSpec read_outputs(const TomlTable& t) {
  OutputsSpec o;
  const std::string mesh = t.opt_choice("part_mesh", {"auto", "full", "simplified", "none"}).value_or("auto");
  o.part_mesh = mesh == "auto"         ? OutputsSpec::Mesh::Auto
                : mesh == "full"       ? OutputsSpec::Mesh::Full
                : mesh == "simplified" ? OutputsSpec::Mesh::Simplified
                                       : OutputsSpec::Mesh::None;
  const std::string csv = t.opt_choice("csv", {"auto", "always", "never"}).value_or("auto");
  o.csv = csv == "auto" ? OutputsSpec::Csv::Auto : csv == "always" ? OutputsSpec::Csv::Always : OutputsSpec::Csv::Never;
  o.npy = t.opt_boolean("npy").value_or(true);
  o.x3p = t.opt_boolean("x3p").value_or(true);
  if (auto n = t.opt_integer("large_grid_nodes")) {
    if (*n < 1) t.fail("large_grid_nodes", fmt::format("expected a number of grid nodes >= 1, found {}", *n));
    o.large_grid_nodes = static_cast<double>(*n);
  }
  if (auto tol = t.opt_positive("mesh_tolerance_mm")) o.mesh_tolerance_mm = *tol;
  if (auto l = t.opt_integer("vtp_compression_level")) {
    if (*l < 1 || *l > 9) t.fail("vtp_compression_level", fmt::format("expected a zlib level 1..9, found {}", *l));
    o.vtp_compression_level = static_cast<int>(*l);
  }
  t.finish();
  return o;
}

}  // namespace

Job load_job(const std::filesystem::path& path) {
  const toml::table root = parse_toml_file(path);
  TomlTable top(root, path.string(), "");
  Job job;
  job.file = path;
  {
    TomlTable jt = top.table("job");
    job.name = jt.opt_string("name").value_or(path.stem().string());
    (void)jt.opt_string("description");
    job.machine_file = jt.existing_path("machine");
    // A [feedplan.nurbs] curve can stand for the program (checked below).
    if (auto p = jt.opt_existing_path("program")) job.program_file = *p;
    job.tool_table_file = jt.opt_existing_path("tool_table");
    job.gain_schedule_file = jt.opt_existing_path("gain_schedule");
    job.feed_plan_file = jt.opt_existing_path("feed_plan");
    if (auto st = jt.opt_numbers("start_mm", 3)) job.start_mm = Eigen::Vector3d((*st)[0], (*st)[1], (*st)[2]);
    if (auto codes = jt.opt_numbers("no_motion_mcodes")) {
      for (double c : *codes) {
        if (c != std::floor(c) || c < 0 || c > 999)
          jt.fail("no_motion_mcodes", fmt::format("expected M code numbers 0..999, found {}", c));
        job.no_motion_mcodes.push_back(static_cast<int>(c));
      }
    }
    job.tcp = jt.opt_boolean("tcp").value_or(false);
    if (auto d = jt.opt_string("program_dialect")) {
      if (*d != "auto" && *d != "rs274ngc" && *d != "sinumerik" && *d != "apt")
        jt.fail("program_dialect", "expected \"auto\", \"rs274ngc\", \"sinumerik\" or \"apt\", found \"" + *d + "\"");
      job.program_dialect = *d;
    }
    job.program_lenient = jt.opt_boolean("program_lenient").value_or(false);
    if (auto u = jt.opt_string("program_units")) {
      if (*u != "mm" && *u != "inch")
        jt.fail("program_units",
                "expected \"mm\" or \"inch\" (the unit of an APT CL file without UNITS/), found \"" + *u + "\"");
      job.program_units = *u;
    }
    // Identified axis models (vmsim identify) run instead of the drives of the machine file (drives/axis_model_file).
    job.axis_models_file = jt.opt_existing_path("axis_models");
    jt.finish();
  }
  job.machine = load_machine(job.machine_file);
  if (auto t = top.opt_table("tool")) {
    if (top.has("tools"))
      top.fail("tools",
               "the job gives both [tool] and [[tools]] (expected [tool] for a single-tool job, or one "
               "[[tools]] per T number)");
    job.tool = read_tool(*t);
    job.tool_all_numbers = t->opt_boolean("all_tools").value_or(false);
    t->finish();
    job.tool_given = true;
  }
  if (top.has("tools")) job.tools = read_tools(top);
  if (auto t = top.opt_table("stock")) job.stock = read_stock(*t);
  if (auto t = top.opt_table("interpolation")) job.interp = read_interp(*t);
  if (auto t = top.opt_table("removal")) job.removal = read_removal(*t);
  if (auto t = top.opt_table("reference")) job.reference = read_reference(*t);
  if (auto t = top.opt_table("feedplan")) job.feedplan = read_feedplan(*t);
  if (auto t = top.opt_table("outputs")) job.outputs = read_outputs(*t);
  if (job.program_file.empty() && !(job.feedplan && job.feedplan->nurbs))
    top.table("job").fail("program", "missing (expected a file path, or a [feedplan.nurbs] curve as the path)");
  if (job.reference.kind == ReferenceSpec::Kind::Stock && job.stock.kind != StockSpec::Kind::Job)
    top.fail("reference", "kind = \"stock\" needs a stock of type \"job\" (the part another job leaves)");
  top.finish();
  // Every input path goes into report.json (and X3P comments): one that is not UTF-8 is refused now, not lost after
  // the run.
  {
    std::error_code ec;
    const auto check = [&](const std::filesystem::path& p, const char* what) {
      if (p.empty()) return;
      const std::filesystem::path full = std::filesystem::weakly_canonical(p, ec);
      require_utf8_path(ec ? p : full, what);
    };
    check(path, "the job file's path");
    check(job.machine_file, "[job] machine");
    check(job.program_file, "[job] program");
    if (job.tool_table_file) check(*job.tool_table_file, "[job] tool_table");
    if (job.gain_schedule_file) check(*job.gain_schedule_file, "[job] gain_schedule");
    if (job.feed_plan_file) check(*job.feed_plan_file, "[job] feed_plan");
    if (job.axis_models_file) check(*job.axis_models_file, "[job] axis_models");
  }
  return job;
}

}  // namespace vmsim::core
