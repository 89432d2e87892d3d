#include "app/cmd_surface.hpp"

#include "app/commands.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cmath>

namespace vmsim::app {

double parse_length_mm(const std::string& text, const std::string& option) {
  std::size_t k = 0;
  while (k < text.size() &&
         (std::isdigit(static_cast<unsigned char>(text[k])) || text[k] == '.' || text[k] == '+' || text[k] == '-' ||
          ((text[k] == 'e' || text[k] == 'E') && k + 1 < text.size() &&
           (std::isdigit(static_cast<unsigned char>(text[k + 1])) || text[k + 1] == '-' || text[k + 1] == '+'))))
    ++k;
  const std::string number = text.substr(0, k), unit = text.substr(k);
  int pow10 = -3;
  if (unit.find_first_not_of(' ') != std::string::npos) {
    const auto p = metrology::length_unit_pow10(unit);
    if (!p)
      throw core::Error(fmt::format("{}: unknown unit in \"{}\" (write e.g. 5um, 0.005mm or 0.005)", option, text));
    pow10 = *p;
  }
  const auto v = metrology::parse_decimal_scaled(number, pow10 + 3);
  if (!v || !std::isfinite(*v))
    throw core::Error(fmt::format("{}: \"{}\" is not a length (write e.g. 5um, 0.005mm or 0.005)", option, text));
  return *v;
}

int parse_level(const std::string& t) {
  if (t == "none") return 0;
  if (t == "plane") return 1;
  if (t.rfind("poly:", 0) == 0) {
    const std::string n = t.substr(5);
    if (!n.empty() && n.size() <= 2 && std::isdigit(static_cast<unsigned char>(n[0])) &&
        (n.size() == 1 || std::isdigit(static_cast<unsigned char>(n[1])))) {
      const int d = std::stoi(n);
      if (d >= 1 && d <= 10) return d;
    }
  }
  throw core::Error("--level: expected none, plane or poly:N (N = 1..10), found \"" + t + "\"");
}

std::vector<metrology::SurfaceFilter> parse_filters(const std::vector<std::string>& texts) {
  std::vector<metrology::SurfaceFilter> out;
  for (const std::string& t : texts) {
    if (t.size() < 3 || (t[0] != 'S' && t[0] != 'L' && t[0] != 's' && t[0] != 'l') || t[1] != ':')
      throw core::Error("--filter: expected S:<cut-off> or L:<cut-off> (e.g. L:0.8mm, S:2.5um), found \"" + t + "\"");
    metrology::SurfaceFilter f;
    f.kind = static_cast<char>(std::toupper(static_cast<unsigned char>(t[0])));
    f.cutoff_mm = parse_length_mm(t.substr(2), "--filter");
    if (!(f.cutoff_mm > 0)) throw core::Error("--filter: the cut-off must be positive, found \"" + t + "\"");
    out.push_back(f);
  }
  return out;
}

metrology::SurfaceProcessing parse_processing(const SurfaceOptions& options) {
  metrology::SurfaceProcessing how;
  how.level = parse_level(options.level);
  how.filters = parse_filters(options.filters);
  return how;
}

nlohmann::json processing_json(const metrology::SurfaceProcessing& how, const std::optional<metrology::FormFit>& form) {
  nlohmann::json log;
  if (how.level > 0 && form) {
    log["level"] = {{"form", how.level == 1 ? std::string("plane") : fmt::format("poly:{}", how.level)},
                    {"slope_x", form->slope_x},
                    {"slope_y", form->slope_y},
                    {"z_centre_mm", form->z_centre_mm},
                    {"rms_residual_mm", form->rms_residual_mm}};
  } else {
    log["level"] = {{"form", "none"}};
  }
  nlohmann::json fl = nlohmann::json::array();
  for (const metrology::SurfaceFilter& f : how.filters)
    fl.push_back(
        {{"type", f.kind == 'S' ? "S (Gaussian low-pass, ISO 16610-61)" : "L (Gaussian high-pass, ISO 16610-61)"},
         {"cutoff_mm", f.cutoff_mm},
         {"edges", "weights renormalised over the valid points in the window (ISO 16610-28 zero-order)"}});
  log["filters"] = fl;
  return log;
}

namespace {
nlohmann::json json_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
}  // namespace

nlohmann::json areal_json(const metrology::ArealParameters& p) {
  return {{"points", p.points},
          {"mean_mm", json_or_null(p.mean_mm)},
          {"Sa_mm", json_or_null(p.Sa_mm)},
          {"Sq_mm", json_or_null(p.Sq_mm)},
          {"Sp_mm", json_or_null(p.Sp_mm)},
          {"Sv_mm", json_or_null(p.Sv_mm)},
          {"Sz_mm", json_or_null(p.Sz_mm)},
          {"Ssk", json_or_null(p.Ssk)},
          {"Sku", json_or_null(p.Sku)},
          {"Sdq", json_or_null(p.Sdq)},
          {"Sdr_percent", json_or_null(p.Sdr_percent)}};
}

metrology::LineScan profile_in_range(const metrology::LineScan& p, const std::string& range) {
  if (range.empty()) return p;
  const auto comma = range.find(',');
  if (comma == std::string::npos)
    throw core::Error("--range: expected X0,X1 (lengths, e.g. 468um,733um), found \"" + range + "\"");
  const double a = parse_length_mm(range.substr(0, comma), "--range"),
               b = parse_length_mm(range.substr(comma + 1), "--range");
  if (!(b > a)) throw core::Error("--range: X0 must be less than X1, found \"" + range + "\"");
  // From the sample nearest to X0 to the one nearest to X1, as an instrument's cursors take them.
  return metrology::crop(p, a - p.dx_mm / 2, b + p.dx_mm / 2);
}

nlohmann::json line_scan_json(const metrology::LineScan& p) {
  std::size_t invalid = 0;
  for (Eigen::Index k = 0; k < p.size(); ++k) invalid += std::isfinite(p.z_mm[k]) ? 0 : 1;
  return {{"points", p.size()},
          {"dx_mm", p.dx_mm},
          {"x0_mm", p.x0_mm},
          {"length_mm", p.length_mm()},
          {"invalid_points", invalid}};
}

nlohmann::json profile_json(const metrology::EvaluatedProfile& e, const metrology::ProfileEvaluation& how) {
  const metrology::ProfileParameters& r = e.parameters;
  nlohmann::json filters = nlohmann::json::array();
  for (const auto& f : how.filters)
    filters.push_back({{"type", f.kind == 'S' ? "S (Gaussian mean line kept, ISO 16610-21)"
                                              : "L (Gaussian mean line removed, ISO 16610-21)"},
                       {"cutoff_mm", f.cutoff_mm}});
  return {{"standard", "ISO 21920-2 (heights from the mean line of the evaluated profile)"},
          {"form_removed", how.level == 0   ? std::string("none (the mean line)")
                           : how.level == 1 ? std::string("least-squares line")
                                            : fmt::format("polynomial of degree {}", how.level)},
          {"filters", filters},
          {"ends", "after an L-filter, half a cut-off dropped at each end (run-in, run-out)"},
          {"x_from_mm", e.profile.x0_mm},
          {"x_to_mm", e.profile.x(e.profile.size() - 1)},
          {"points", r.points},
          {"evaluation_length_mm", r.evaluation_length_mm},
          {"sections", r.sections},
          {"section_length_mm", r.section_length_mm},
          {"Ra_mm", json_or_null(r.Ra_mm)},
          {"Rq_mm", json_or_null(r.Rq_mm)},
          {"Rsk", json_or_null(r.Rsk)},
          {"Rku", json_or_null(r.Rku)},
          {"Rp_mm", json_or_null(r.Rp_mm)},
          {"Rv_mm", json_or_null(r.Rv_mm)},
          {"Rz_mm", json_or_null(r.Rz_mm)},
          {"Rt_mm", json_or_null(r.Rt_mm)},
          {"Rzx_mm", json_or_null(r.Rzx_mm)}};
}

nlohmann::json grid_json(const core::HeightGrid& g) {
  std::size_t invalid = 0;
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) invalid += std::isfinite(g.z_mm.data()[k]) ? 0 : 1;
  return {{"nx", g.nx()},
          {"ny", g.ny()},
          {"dx_mm", g.dx_mm},
          {"dy_mm", g.dy_mm},
          {"x0_mm", g.x0_mm},
          {"y0_mm", g.y0_mm},
          {"points", static_cast<std::size_t>(g.z_mm.size())},
          {"invalid_points", invalid}};
}

nlohmann::json input_json(const std::filesystem::path& file, const std::string& format) {
  std::error_code ec;
  const auto abs = std::filesystem::weakly_canonical(file, ec);
  return {{"path", (ec ? file : abs).string()}, {"sha256", core::sha256_file_hex(file)}, {"format", format}};
}

}  // namespace vmsim::app
