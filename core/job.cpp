#include "core/job.hpp"

#include "core/error.hpp"
#include "core/toml_reader.hpp"

#include <fmt/format.h>

#include <cmath>

namespace vmsim::core {

namespace {

ToolSpec read_tool(const TomlTable& t) {
  ToolSpec tool;
  const std::string type = t.choice("type", {"ball", "flat", "bullnose"});
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
      t.fail("corner_radius_mm", fmt::format("expected less than the radius {} mm (use type = \"ball\")",
                                             tool.diameter_mm / 2));
  }
  tool.flute_length_mm = t.opt_positive("flute_length_mm").value_or(2 * tool.diameter_mm);
  tool.length_mm = t.opt_positive("length_mm").value_or(std::max(50.0, tool.flute_length_mm));
  if (tool.length_mm < tool.flute_length_mm) t.fail("length_mm", "expected at least flute_length_mm");
  t.finish();
  return tool;
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
  r.field = field == "zmap" ? RemovalSpec::Field::ZMap
            : field == "tridexel" ? RemovalSpec::Field::TriDexel
                                  : RemovalSpec::Field::NBuffer;
  if (auto h = t.opt_positive("spacing_mm")) {
    if (*h < 1e-4) t.fail("spacing_mm", "expected at least 0.0001 mm");
    r.spacing_mm = *h;
  }
  const std::string motion = t.opt_choice("motion", {"actual", "setpoints", "program"}).value_or("actual");
  r.motion = motion == "actual" ? RemovalSpec::Motion::Actual
             : motion == "setpoints" ? RemovalSpec::Motion::Setpoints
                                     : RemovalSpec::Motion::Program;
  if (auto tol = t.opt_positive("track_tolerance_mm")) r.track_tolerance_mm = *tol;
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
  if (r.kind == ReferenceSpec::Kind::Job) r.job_file = t.existing_path("job");
  else if (t.has("job")) t.fail("job", "only valid with kind = \"job\"");
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
  if (auto tol = t.opt_positive("tolerance_mm")) spec.tolerance_mm = *tol;
  t.finish();
  return spec;
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
    job.program_file = jt.existing_path("program");
    job.tool_table_file = jt.opt_existing_path("tool_table");
    job.gain_schedule_file = jt.opt_existing_path("gain_schedule");
    if (auto st = jt.opt_numbers("start_mm", 3)) job.start_mm = Eigen::Vector3d((*st)[0], (*st)[1], (*st)[2]);
    if (auto codes = jt.opt_numbers("no_motion_mcodes")) {
      for (double c : *codes) {
        if (c != std::floor(c) || c < 0 || c > 999)
          jt.fail("no_motion_mcodes", fmt::format("expected M code numbers 0..999, found {}", c));
        job.no_motion_mcodes.push_back(static_cast<int>(c));
      }
    }
    job.tcp = jt.opt_boolean("tcp").value_or(false);
    jt.finish();
  }
  job.machine = load_machine(job.machine_file);
  if (auto t = top.opt_table("tool")) job.tool = read_tool(*t);
  if (auto t = top.opt_table("stock")) job.stock = read_stock(*t);
  if (auto t = top.opt_table("interpolation")) job.interp = read_interp(*t);
  if (auto t = top.opt_table("removal")) job.removal = read_removal(*t);
  if (auto t = top.opt_table("reference")) job.reference = read_reference(*t);
  if (job.reference.kind == ReferenceSpec::Kind::Stock && job.stock.kind != StockSpec::Kind::Job)
    top.fail("reference", "kind = \"stock\" needs a stock of type \"job\" (the part another job leaves)");
  top.finish();
  return job;
}

}  // namespace vmsim::core
