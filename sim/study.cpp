#include "sim/study.hpp"

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/toml_reader.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

namespace vmsim::sim {

namespace {

namespace fs = std::filesystem;

// Top-level tables of a job file (core/job.cpp) and of a machine file (core/machine.cpp): the first key of an
// override must be one of them, so a typo there is an error of the study file, before anything runs.
const std::set<std::string> kJobTables = {"job", "tool", "stock", "interpolation", "removal", "reference", "feedplan"};
const std::set<std::string> kMachineTables = {"machine", "kinematics", "axes"};

// The job keys that hold file paths (parts/README.md): resolved against the job file's directory when it is read, so
// a variation's job, written elsewhere, carries them absolute.
const std::vector<std::string> kJobPathKeys = {
    "job.machine",         "job.program", "job.tool_table", "job.gain_schedule",    "job.axis_models",
    "stock.file",          "stock.job",   "reference.job",  "removal.needles_file", "feedplan.nurbs.control_points",
    "feedplan.nurbs.knots"};

std::string where(const std::string& file, const toml::node& n) {
  const auto& s = n.source();
  return s.begin.line > 0 ? fmt::format("{}:{}:{}", file, s.begin.line, s.begin.column) : file;
}

[[noreturn]] void fail_at(const std::string& file, const toml::node& n, const std::string& key,
                          const std::string& msg) {
  throw core::Error(fmt::format("{}: key '{}': {}", where(file, n), key, msg));
}

std::vector<std::string> split_key(const std::string& key) {
  std::vector<std::string> out;
  std::string seg;
  std::stringstream ss(key);
  while (std::getline(ss, seg, '.')) out.push_back(seg);
  return out;
}

// A value as TOML text (what the variation's files get) and as a table cell (strings without their quotes).
std::string toml_text(const toml::node& n) {
  toml::table t;
  t.insert("v", n);
  std::ostringstream os;
  os << toml::toml_formatter(t, toml::format_flags::none);
  std::string s = os.str();
  s = s.substr(s.find('=') + 1);
  while (!s.empty() && (s.front() == ' ')) s.erase(s.begin());
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}
std::string cell_text(const toml::node& n) {
  if (auto s = n.value<std::string>(); s && n.is_string()) return *s;
  // The shortest decimal that reads back as the same number (toml++ writes 17 digits: 0.0050000000000000001).
  if (auto v = n.value<double>(); v && n.is_floating_point()) return fmt::format("{}", *v);
  return toml_text(n);
}

// The leaves of a table of overrides (nested tables, from dotted keys, are walked), in the order the file writes
// them (toml++ keeps keys sorted; the grid's order is the file's).
struct Leaf {
  std::string key;
  const toml::node* node;
};
void leaves(const toml::table& t, const std::string& prefix, std::vector<Leaf>& out) {
  for (const auto& [k, n] : t) {
    const std::string key = prefix.empty() ? std::string(k.str()) : prefix + "." + std::string(k.str());
    if (const toml::table* sub = n.as_table())
      leaves(*sub, key, out);
    else
      out.push_back({key, &n});
  }
}
std::vector<Leaf> ordered_leaves(const toml::table& t) {
  std::vector<Leaf> out;
  leaves(t, "", out);
  std::stable_sort(out.begin(), out.end(), [](const Leaf& a, const Leaf& b) {
    const auto &sa = a.node->source().begin, &sb = b.node->source().begin;
    return std::pair(sa.line, sa.column) < std::pair(sb.line, sb.column);
  });
  return out;
}

// Checks an override's key (where it can go) and, for feed_scale, its value.
void check_key(const std::string& file, const std::string& key, const toml::node& n, bool allow_name) {
  const std::vector<std::string> segs = split_key(key);
  for (const std::string& s : segs)
    if (s.empty()) fail_at(file, n, key, "an empty part in the dotted key");
  const std::string& top = segs.front();
  if (key == "feed_scale") {
    auto v = n.value<double>();
    if (!(n.is_floating_point() || n.is_integer()) || !v || !(*v > 0) || !std::isfinite(*v))
      fail_at(file, n, key,
              "expected a positive number (it multiplies every programmed feed, as vmsim run --feed-scale)");
    return;
  }
  if (allow_name && key == "name") {
    if (!n.is_string()) fail_at(file, n, key, "expected a string");
    return;
  }
  if (top == "machine") {
    if (segs.size() < 3 || !kMachineTables.count(segs[1]))
      fail_at(file, n, key,
              "expected machine.<key of the machine file>, e.g. machine.axes.X.drive.kv_1000_per_min "
              "(the machine file's tables: machine, kinematics, axes)");
    return;
  }
  if (kJobTables.count(top)) {
    if (segs.size() < 2) fail_at(file, n, key, fmt::format("expected a key inside [{}], e.g. {}.<key>", top, top));
    return;
  }
  fail_at(file, n, key,
          "expected feed_scale, a job key (job., tool., stock., interpolation., removal., reference., feedplan.) or a "
          "machine key (machine.)" +
              std::string(allow_name ? " or name" : ""));
}

StudyOverride make_override(const std::string& file, const std::string& key, const toml::node& n) {
  return {key, toml_text(n), cell_text(n), where(file, n)};
}

// Sets `segs[i..]` below `node` to `value`. Tables on the way are created; an array of tables is entered at the
// element whose name (or axis) is the next part, or at every element for "*".
void apply(toml::node& node, const std::vector<std::string>& segs, std::size_t i, const toml::node& value,
           const std::string& done) {
  const std::string& seg = segs[i];
  const std::string here = done.empty() ? seg : done + "." + seg;
  if (toml::table* t = node.as_table()) {
    if (i + 1 == segs.size()) {
      t->insert_or_assign(seg, value);
      return;
    }
    if (!t->contains(seg)) t->insert(seg, toml::table{});
    apply(*t->get(seg), segs, i + 1, value, here);
    return;
  }
  if (toml::array* a = node.as_array(); a && a->is_array_of_tables()) {
    if (i + 1 == segs.size())
      throw core::Error(fmt::format("'{}' is an array of tables: name a key inside one element", done));
    std::vector<std::string> names;
    bool found = false;
    for (toml::node& el : *a) {
      toml::table& et = *el.as_table();
      std::optional<std::string> name = et["name"].value<std::string>();
      if (!name) name = et["axis"].value<std::string>();
      if (name) names.push_back(*name);
      if (seg == "*" || (name && *name == seg)) {
        found = true;
        apply(el, segs, i + 1, value, here);
      }
    }
    if (!found)
      throw core::Error(
          fmt::format("'{}' has no element named '{}' (it has: {}; \"*\" sets every element)", done, seg,
                      names.empty() ? std::string("no named elements") : fmt::format("{}", fmt::join(names, ", "))));
    return;
  }
  throw core::Error(fmt::format("'{}' is {}, not a table", done, node.is_array() ? "an array of values" : "a value"));
}

toml::table parse_value(const std::string& text) { return toml::parse("v = " + text); }

fs::path absolute_of(const fs::path& p, const fs::path& dir) {
  return (p.is_relative() ? fs::absolute(dir / p) : p).lexically_normal();
}

// The string at a dotted path of a table (nullptr when absent or not a string).
toml::value<std::string>* string_at(toml::table& root, const std::string& key) {
  toml::node* n = &root;
  for (const std::string& s : split_key(key)) {
    toml::table* t = n->as_table();
    if (!t || !t->contains(s)) return nullptr;
    n = t->get(s);
  }
  return n->as_string();
}

std::string format_toml(const toml::table& t) {
  std::ostringstream os;
  os << toml::toml_formatter(t) << "\n";
  return os.str();
}

std::string csv_cell(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string num(const std::optional<double>& v, double scale) {
  return v ? fmt::format("{}", *v * scale) : std::string();
}

const char* status_name(StudyResult::Status s) {
  switch (s) {
    case StudyResult::Status::Ok:
      return "ok";
    case StudyResult::Status::Failed:
      return "failed";
    case StudyResult::Status::Pending:
      return "pending";
  }
  return "?";
}

}  // namespace

Study load_study(const fs::path& path) {
  const toml::table root = core::parse_toml_file(path);
  const std::string file = path.string();
  Study study;
  study.file = path;
  for (const auto& [k, n] : root)
    if (!std::set<std::string>{"study", "common", "grid", "variation"}.count(std::string(k.str())))
      fail_at(file, n, std::string(k.str()), "unknown key (expected [study], [common], [grid] or [[variation]])");
  {
    core::TomlTable st = core::TomlTable(root, file, "").table("study");
    study.name = st.opt_string("name").value_or(path.stem().string());
    (void)st.opt_string("description");
    study.base_job = st.existing_path("job");
    st.finish();
  }
  std::vector<StudyOverride> common;
  if (const toml::node* c = root.get("common")) {
    if (!c->is_table()) fail_at(file, *c, "common", "expected a table of overrides");
    for (const Leaf& l : ordered_leaves(*c->as_table())) {
      check_key(file, l.key, *l.node, false);
      common.push_back(make_override(file, l.key, *l.node));
    }
  }
  const toml::node* grid = root.get("grid");
  const toml::node* list = root.get("variation");
  if (grid && list) fail_at(file, *grid, "grid", "a study has either a [grid] or [[variation]] tables, not both");
  auto add_varied = [&](const std::string& key) {
    if (std::find(study.varied_keys.begin(), study.varied_keys.end(), key) == study.varied_keys.end())
      study.varied_keys.push_back(key);
  };
  if (grid) {
    if (!grid->is_table()) fail_at(file, *grid, "grid", "expected a table: key = [values]");
    const std::vector<Leaf> axes = ordered_leaves(*grid->as_table());
    if (axes.empty()) fail_at(file, *grid, "grid", "expected at least one key = [values]");
    std::vector<std::vector<StudyOverride>> values(axes.size());
    double count = 1;
    for (std::size_t a = 0; a < axes.size(); ++a) {
      const std::string key = "grid." + axes[a].key;
      const toml::array* arr = axes[a].node->as_array();
      if (!arr || arr->empty())
        fail_at(file, *axes[a].node, key, "expected a non-empty array of the values to take (key = [v1, v2, ...])");
      for (const toml::node& v : *arr) {
        check_key(file, axes[a].key, v, false);
        StudyOverride o = make_override(file, axes[a].key, v);
        values[a].push_back(o);
      }
      count *= static_cast<double>(arr->size());
      add_varied(axes[a].key);
    }
    if (count > 1e6) fail_at(file, *grid, "grid", fmt::format("{:.3g} variations; expected at most 1000000", count));
    // Names: each key by its shortest tail that no other grid key ends with (kv_1000_per_min, or
    // X.drive.kv_1000_per_min and Z.drive.kv_1000_per_min when both vary).
    std::vector<std::string> short_key(axes.size());
    for (std::size_t a = 0; a < axes.size(); ++a) {
      const std::vector<std::string> segs = split_key(axes[a].key);
      for (std::size_t k = 1; k <= segs.size(); ++k) {
        std::string tail;
        for (std::size_t j = segs.size() - k; j < segs.size(); ++j) {
          if (!tail.empty()) tail += '.';
          tail += segs[j];
        }
        bool unique = true;
        for (std::size_t b = 0; b < axes.size(); ++b) {
          const std::string& other = axes[b].key;  // ends with the tail at a key boundary
          const bool ends = other.size() >= tail.size() &&
                            other.compare(other.size() - tail.size(), tail.size(), tail) == 0 &&
                            (other.size() == tail.size() || other[other.size() - tail.size() - 1] == '.');
          if (b != a && ends) unique = false;
        }
        short_key[a] = tail;
        if (unique) break;
      }
    }
    // Cartesian product; the first key varies slowest (nested loops in the file's order).
    const auto n = static_cast<std::size_t>(count);
    for (std::size_t k = 0; k < n; ++k) {
      StudyVariation v;
      v.index = static_cast<int>(k) + 1;
      v.overrides = common;
      std::size_t rest = k;
      std::vector<std::string> parts(axes.size());
      std::vector<StudyOverride> own(axes.size());
      for (std::size_t a = axes.size(); a-- > 0;) {
        own[a] = values[a][rest % values[a].size()];
        rest /= values[a].size();
        parts[a] = short_key[a] + "=" + own[a].value_cell;
      }
      v.overrides.insert(v.overrides.end(), own.begin(), own.end());
      v.name = fmt::format("{}", fmt::join(parts, " "));
      study.variations.push_back(std::move(v));
    }
  } else if (list) {
    const toml::array* arr = list->as_array();
    if (!arr || !arr->is_array_of_tables() || arr->empty())
      fail_at(file, *list, "variation", "expected [[variation]] tables, one per variation");
    std::set<std::string> names;
    for (std::size_t k = 0; k < arr->size(); ++k) {
      const toml::table& t = *(*arr)[k].as_table();
      StudyVariation v;
      v.index = static_cast<int>(k) + 1;
      v.name = std::to_string(v.index);
      v.overrides = common;
      for (const Leaf& l : ordered_leaves(t)) {
        check_key(file, l.key, *l.node, true);
        if (l.key == "name") {
          v.name = *l.node->value<std::string>();
          if (v.name.empty()) fail_at(file, *l.node, "variation.name", "expected a non-empty name");
          if (!names.insert(v.name).second)
            fail_at(file, *l.node, "variation.name", "\"" + v.name + "\" names another variation already");
          continue;
        }
        v.overrides.push_back(make_override(file, l.key, *l.node));
        add_varied(l.key);
      }
      study.variations.push_back(std::move(v));
    }
  } else {
    throw core::Error(file + ": expected a [grid] table or [[variation]] tables (the variations of the base job)");
  }
  return study;
}

PreparedVariation prepare_variation(const Study& study, const StudyVariation& v) {
  const std::string label = fmt::format("{}: variation {} ({})", study.file.string(), v.index, v.name);
  PreparedVariation out;
  toml::table job;
  try {
    job = core::parse_toml_file(study.base_job);
  } catch (const core::Error& e) {
    throw core::Error(label + ": " + e.what());
  }
  const fs::path base_dir = study.base_job.parent_path(), study_dir = study.file.parent_path();
  for (const std::string& key : kJobPathKeys)
    if (auto* s = string_at(job, key)) **s = absolute_of(fs::path(**s), base_dir).string();
  // The job's name is its file's stem by default: the variation keeps the base job's.
  if (toml::table* jt = job["job"].as_table(); jt && !jt->contains("name"))
    jt->insert("name", study.base_job.stem().string());

  std::vector<const StudyOverride*> machine_overrides;
  for (const StudyOverride& o : v.overrides) {
    try {
      const toml::table value = parse_value(o.value_toml);
      if (o.key == "feed_scale") {
        out.feed_scale = *value["v"].value<double>();
        continue;
      }
      if (o.key.rfind("machine.", 0) == 0) {
        machine_overrides.push_back(&o);
        continue;
      }
      apply(job, split_key(o.key), 0, *value.get("v"), "");
      if (std::find(kJobPathKeys.begin(), kJobPathKeys.end(), o.key) != kJobPathKeys.end())
        if (auto* s = string_at(job, o.key)) **s = absolute_of(fs::path(**s), study_dir).string();
    } catch (const core::Error& e) {
      throw core::Error(fmt::format("{}: {}: key '{}': {}", label, o.where, o.key, e.what()));
    } catch (const toml::parse_error& e) {
      throw core::Error(fmt::format("{}: {}: key '{}': {}", label, o.where, o.key, e.description()));
    }
  }
  if (!machine_overrides.empty()) {
    const auto* mpath = string_at(job, "job.machine");
    if (!mpath) throw core::Error(label + ": the base job names no [job] machine for the machine.* keys");
    toml::table machine;
    try {
      machine = core::parse_toml_file(fs::path(**mpath));
    } catch (const core::Error& e) {
      throw core::Error(label + ": " + e.what());
    }
    for (const StudyOverride* o : machine_overrides) {
      try {
        const toml::table value = parse_value(o->value_toml);
        std::vector<std::string> segs = split_key(o->key);
        segs.erase(segs.begin());
        apply(machine, segs, 0, *value.get("v"), "machine");
      } catch (const core::Error& e) {
        throw core::Error(fmt::format("{}: {}: key '{}': {}", label, o->where, o->key, e.what()));
      }
    }
    out.machine_toml = format_toml(machine);
    job["job"].as_table()->insert_or_assign("machine", "machine.toml");
  }
  out.job_toml = format_toml(job);
  return out;
}

StudyFigures figures_from_report(const nlohmann::json& r) {
  StudyFigures f;
  if (r.contains("marks") && r["marks"].is_array()) {
    for (const auto& m : r["marks"]) {
      ++f.marks;
      const double d = m.at("depth_mm").get<double>();
      if (!f.mark_depth_mm || d > *f.mark_depth_mm) {
        f.mark_depth_mm = d;
        f.mark_kind = m.at("kind").get<std::string>();
      }
    }
  }
  if (r.contains("surface")) {
    const auto& s = r["surface"];
    if (s.contains("deviation_min_mm")) f.deviation_min_mm = s["deviation_min_mm"].get<double>();
    if (s.contains("deviation_max_mm")) f.deviation_max_mm = s["deviation_max_mm"].get<double>();
  }
  if (r.contains("contour_error") && r["contour_error"].contains("cutting_moves")) {
    const auto& c = r["contour_error"]["cutting_moves"];
    f.contour_error_max_mm = c.at("max_abs_mm").get<double>();
    f.contour_error_rms_mm = c.at("rms_mm").get<double>();
  }
  if (r.contains("interpolation") && r["interpolation"].contains("cycle_time_s"))
    f.cycle_time_s = r["interpolation"]["cycle_time_s"].get<double>();
  return f;
}

nlohmann::json result_to_json(const StudyResult& r) {
  nlohmann::json j = {{"status", status_name(r.status)}, {"cpu_s", r.cpu_s}, {"wall_s", r.wall_s}, {"rank", r.rank}};
  if (!r.error.empty()) j["error"] = r.error;
  const StudyFigures& f = r.figures;
  nlohmann::json fj = {{"marks", f.marks}};
  auto put = [&fj](const char* k, const std::optional<double>& v) {
    if (v) fj[k] = *v;
  };
  put("mark_depth_mm", f.mark_depth_mm);
  if (f.mark_kind) fj["mark_kind"] = *f.mark_kind;
  put("deviation_min_mm", f.deviation_min_mm);
  put("deviation_max_mm", f.deviation_max_mm);
  put("contour_error_max_mm", f.contour_error_max_mm);
  put("contour_error_rms_mm", f.contour_error_rms_mm);
  put("cycle_time_s", f.cycle_time_s);
  j["figures"] = fj;
  return j;
}

StudyResult result_from_json(const nlohmann::json& j) {
  StudyResult r;
  const std::string s = j.at("status").get<std::string>();
  r.status = s == "ok"       ? StudyResult::Status::Ok
             : s == "failed" ? StudyResult::Status::Failed
                             : StudyResult::Status::Pending;
  r.cpu_s = j.value("cpu_s", 0.0);
  r.wall_s = j.value("wall_s", 0.0);
  r.rank = j.value("rank", -1);
  r.error = j.value("error", std::string());
  const auto& f = j.at("figures");
  r.figures.marks = f.value("marks", 0);
  auto get = [&f](const char* k) -> std::optional<double> {
    if (f.contains(k)) return f[k].get<double>();
    return std::nullopt;
  };
  r.figures.mark_depth_mm = get("mark_depth_mm");
  if (f.contains("mark_kind")) r.figures.mark_kind = f["mark_kind"].get<std::string>();
  r.figures.deviation_min_mm = get("deviation_min_mm");
  r.figures.deviation_max_mm = get("deviation_max_mm");
  r.figures.contour_error_max_mm = get("contour_error_max_mm");
  r.figures.contour_error_rms_mm = get("contour_error_rms_mm");
  r.figures.cycle_time_s = get("cycle_time_s");
  return r;
}

std::string results_csv(const Study& study, const std::vector<StudyResult>& results) {
  // Cells appended one by one (GCC 12 warns, wrongly, about "," + std::string: -Wrestrict).
  std::string out = "variation,name,status";
  auto cell = [&out](const std::string& c) {
    out += ',';
    out += c;
  };
  for (const std::string& k : study.varied_keys) cell(csv_cell(k));
  out +=
      ",marks,mark_depth_um,mark_kind,deviation_min_um,deviation_max_um,contour_error_max_um,contour_error_rms_um,"
      "cycle_time_s,cpu_time_s,error\n";
  for (std::size_t i = 0; i < study.variations.size(); ++i) {
    const StudyVariation& v = study.variations[i];
    const StudyResult& r = results[i];
    out += fmt::format("{},{},{}", v.index, csv_cell(v.name), status_name(r.status));
    for (const std::string& k : study.varied_keys) {
      std::string value;
      for (const StudyOverride& o : v.overrides)
        if (o.key == k) value = o.value_cell;  // the last one wins, as in the run
      cell(csv_cell(value));
    }
    const StudyFigures& f = r.figures;
    cell(r.status == StudyResult::Status::Ok ? std::to_string(f.marks) : std::string());
    cell(num(f.mark_depth_mm, 1e3));
    cell(f.mark_kind ? *f.mark_kind : std::string());
    cell(num(f.deviation_min_mm, 1e3));
    cell(num(f.deviation_max_mm, 1e3));
    cell(num(f.contour_error_max_mm, 1e3));
    cell(num(f.contour_error_rms_mm, 1e3));
    cell(num(f.cycle_time_s, 1.0));
    cell(r.status == StudyResult::Status::Pending ? std::string() : fmt::format("{:.3f}", r.cpu_s));
    cell(csv_cell(r.error));
    out += '\n';
  }
  return out;
}

nlohmann::json study_json(const Study& study, const std::vector<StudyResult>& results, int ranks, double wall_s) {
  auto input = [](const fs::path& p) {
    std::error_code ec;
    const auto abs = fs::weakly_canonical(p, ec);
    return nlohmann::json{{"path", (ec ? p : abs).string()}, {"sha256", core::sha256_file_hex(p)}};
  };
  nlohmann::json vars = nlohmann::json::array();
  int ok = 0, failed = 0, pending = 0;
  for (std::size_t i = 0; i < study.variations.size(); ++i) {
    const StudyVariation& v = study.variations[i];
    nlohmann::json ov = nlohmann::json::array();
    for (const StudyOverride& o : v.overrides)
      ov.push_back({{"key", o.key}, {"value", o.value_toml}, {"where", o.where}});
    nlohmann::json j = result_to_json(results[i]);
    j["variation"] = v.index;
    j["name"] = v.name;
    j["overrides"] = ov;
    j["dir"] = fmt::format("variations/{:03d}", v.index);
    vars.push_back(j);
    ok += results[i].status == StudyResult::Status::Ok;
    failed += results[i].status == StudyResult::Status::Failed;
    pending += results[i].status == StudyResult::Status::Pending;
  }
  return {{"vmsim", VMSIM_VERSION},
          {"command", "study"},
          {"study", study.name},
          {"inputs", {{"study", input(study.file)}, {"base_job", input(study.base_job)}}},
          {"ranks", ranks},
          {"summary", {{"variations", study.variations.size()}, {"ok", ok}, {"failed", failed}, {"pending", pending}}},
          {"variations", vars},
          {"timings_s", {{"total", wall_s}}}};
}

fs::path variation_dir(const fs::path& out_dir, const Study&, const StudyVariation& v) {
  return out_dir / "variations" / fmt::format("{:03d}", v.index);
}

}  // namespace vmsim::sim
