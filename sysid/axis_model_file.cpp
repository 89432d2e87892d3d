#include "sysid/axis_model_file.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/toml_reader.hpp"

#include <fmt/format.h>

#include <cmath>
#include <set>

namespace vmsim::sysid {

const IdentifiedAxis* AxisModelFile::find(const std::string& axis) const {
  for (const auto& a : axes)
    if (a.name == axis) return &a;
  return nullptr;
}

namespace {

Eigen::VectorXd vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

std::string list(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) s += fmt::format("{}{:.17g}", i ? ", " : "", v[i]);
  return s + "]";
}

std::string quoted(const std::string& v) {
  std::string s = "\"";
  for (char ch : v) {
    if (ch == '"' || ch == '\\') s += '\\';
    if (static_cast<unsigned char>(ch) >= 0x20) s += ch;
  }
  return s + "\"";
}

}  // namespace

AxisModelFile load_axis_models(const std::filesystem::path& path) {
  const toml::table root = core::parse_toml_file(path);
  const std::string file = path.string();
  core::TomlTable top(root, file, "");
  AxisModelFile out;
  out.source_file = file;
  const core::TomlTable model = top.table("model");
  out.period_s = model.positive("period_ms") * 1e-3;
  out.trace = model.opt_string("trace").value_or("");
  (void)model.opt_string("created_by");
  model.finish();
  std::set<std::string> seen;
  const std::vector<core::TomlTable> axes = top.array_of_tables("axes");
  if (axes.empty()) top.fail("axes", "expected at least one [[axes]] table");
  for (const core::TomlTable& t : axes) {
    IdentifiedAxis a;
    a.name = t.choice("name", {"X", "Y", "Z", "A", "B", "C"});
    if (!seen.insert(a.name).second) t.fail("name", "axis " + a.name + " appears twice");
    a.structure = *parse_structure(t.choice("structure", {"arx", "armax", "oe"}));
    const long long nk = t.integer("nk");
    if (nk < 1 || nk > 100) t.fail("nk", fmt::format("expected a delay in [1, 100] samples, found {}", nk));
    a.tf.nk = static_cast<int>(nk);
    const std::vector<double> b = t.numbers("b"), av = t.numbers("a");
    if (b.empty() || b.size() > 30) t.fail("b", fmt::format("expected 1 to 30 coefficients, found {}", b.size()));
    if (av.size() > 30) t.fail("a", fmt::format("expected at most 30 coefficients, found {}", av.size()));
    a.tf.b = vec(b);
    a.tf.a = vec(av);
    a.tf.period_s = out.period_s;
    const double r = drives::spectral_radius(a.tf.a);
    if (!(r < 1.0))
      t.fail("a", fmt::format("the model is unstable: a pole of A lies at |z| = {:.6g} (must be < 1)", r));
    if (const auto c = t.opt_numbers("c")) {
      if (a.structure != ModelStructure::Armax) t.fail("c", "only an armax model has a noise numerator c");
      a.c = vec(*c);
    }
    a.fit_percent = t.opt_number("fit_percent");
    a.tracking_fit_percent = t.opt_number("tracking_fit_percent");
    t.finish();
    out.axes.push_back(std::move(a));
  }
  top.finish();
  return out;
}

void save_axis_models(const std::filesystem::path& path, const AxisModelFile& m,
                      const std::vector<std::string>& comment_lines) {
  std::string s;
  for (const auto& l : comment_lines) s += "# " + l + "\n";
  s += "[model]\n";
  s += fmt::format("period_ms = {:.17g}\n", m.period_s * 1e3);
  if (!m.trace.empty()) s += "trace = " + quoted(m.trace) + "\n";
  s += "created_by = \"vmsim identify\"\n";
  for (const IdentifiedAxis& a : m.axes) {
    s += "\n[[axes]]\n";
    s += fmt::format("name = \"{}\"\n", a.name);
    s += fmt::format("structure = \"{}\"\n", structure_name(a.structure));
    s += fmt::format("nk = {}\n", a.tf.nk);
    s += "b = " + list(a.tf.b) + "\n";
    s += "a = " + list(a.tf.a) + "\n";
    if (a.c.size() > 0) s += "c = " + list(a.c) + "\n";
    if (a.fit_percent) s += fmt::format("fit_percent = {:.6f}\n", *a.fit_percent);
    if (a.tracking_fit_percent) s += fmt::format("tracking_fit_percent = {:.6f}\n", *a.tracking_fit_percent);
  }
  core::write_file_atomic(path, s);
}

}  // namespace vmsim::sysid
