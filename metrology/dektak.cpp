#include "metrology/dektak.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

namespace vmsim::metrology {

namespace {

constexpr std::size_t kMaxSamples = std::size_t{1} << 28;

std::string trim_blanks_and_nul(std::string_view s) {
  while (!s.empty() && (std::isspace(static_cast<unsigned char>(s.front())) || s.front() == '\0')) s.remove_prefix(1);
  while (!s.empty() && (std::isspace(static_cast<unsigned char>(s.back())) || s.back() == '\0')) s.remove_suffix(1);
  return std::string(s);
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::size_t p = 0;
  for (;;) {
    const std::size_t c = line.find(',', p);
    out.push_back(trim_blanks_and_nul(std::string_view(line).substr(p, c == std::string::npos ? std::string::npos : c - p)));
    if (c == std::string::npos) break;
    p = c + 1;
  }
  return out;
}

// The length unit a column header names: a unit token ("um", latin-1 or UTF-8 "µm", "nm", "A") or a word
// ("Micrometer", "Nanometer", "Angstrom", "Millimeter"), alone or in parentheses or brackets.
std::optional<int> column_unit(const std::string& header) {
  std::string t;
  for (char c : header) t += (c == '(' || c == ')' || c == '[' || c == ']' || c == '/') ? ' ' : c;
  std::istringstream ss(t);
  std::string w;
  std::optional<int> found;
  while (ss >> w) {
    std::string l = w;
    for (char& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (l == "micrometer" || l == "micrometers" || l == "microns")
      found = -6;
    else if (l == "nanometer" || l == "nanometers")
      found = -9;
    else if (l == "angstrom" || l == "angstroms")
      found = -10;
    else if (l == "millimeter" || l == "millimeters")
      found = -3;
    else if (const auto p = length_unit_pow10(w))
      found = *p;
  }
  return found;
}

int decimals(std::string_view s) {
  const std::size_t dot = s.find('.');
  if (dot == std::string_view::npos) return 0;
  std::size_t e = s.find_first_of("eE", dot);
  if (e == std::string_view::npos) e = s.size();
  return static_cast<int>(e - dot - 1);
}

}  // namespace

bool looks_like_dektak(std::string_view head) {
  return head.find("Scan Data") != std::string_view::npos && head.find("Lateral") != std::string_view::npos
             ? true
             : head.rfind("Scan Parameters", 0) == 0;
}

DektakData read_dektak_csv(std::string_view text, const std::string& name) {
  const auto fail_line = [&](int line, const std::string& what) {
    throw core::Error(fmt::format("{}:{}: {}", name, line, what));
  };
  std::vector<std::string> lines;
  {
    std::size_t p = 0;
    while (p < text.size()) {
      std::size_t e = text.find('\n', p);
      if (e == std::string_view::npos) e = text.size();
      std::string l(text.substr(p, e - p));
      while (!l.empty() && l.back() == '\r') l.pop_back();
      lines.push_back(std::move(l));
      p = e + 1;
    }
  }
  // The column header: the first line starting with "Lateral" (after "Scan Data" when there is one).
  std::size_t head = lines.size();
  for (std::size_t k = 0; k < lines.size(); ++k)
    if (lines[k].rfind("Lateral", 0) == 0) {
      head = k;
      break;
    }
  if (head == lines.size())
    throw core::Error(name +
                      ": no \"Lateral ...\" column header (a Dektak export names its columns after \"Scan Data\")");
  const std::vector<std::string> cols = split_csv(lines[head]);
  if (cols.size() < 2 || cols[1].empty())
    fail_line(static_cast<int>(head + 1), "expected the lateral and a height column");
  const auto px = column_unit(cols[0]);
  if (!px) fail_line(static_cast<int>(head + 1), "the column \"" + cols[0] + "\" names no length unit (um, nm, mm, A)");
  const auto pz = column_unit(cols[1]);
  if (!pz)
    fail_line(static_cast<int>(head + 1),
              "the column \"" + cols[1] + "\" names no length unit (Micrometer, um, nm, A)");
  std::vector<double> xs, zs;
  int dec = 0;
  for (std::size_t k = head + 1; k < lines.size(); ++k) {
    const std::string t = trim_blanks_and_nul(lines[k]);
    if (t.empty()) {
      if (!xs.empty()) break;  // the data end at the first blank line
      continue;
    }
    const std::vector<std::string> f = split_csv(t);
    if (f.size() < 2) fail_line(static_cast<int>(k + 1), "expected \"x,z\"");
    const auto x = parse_decimal_scaled(f[0], *px + 3);
    if (!x || !std::isfinite(*x))
      fail_line(static_cast<int>(k + 1), "lateral value \"" + f[0].substr(0, 30) + "\" is not a number");
    std::optional<double> z;
    const std::string zl = [&] {
      std::string l = f[1];
      for (char& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return l;
    }();
    if (f[1].empty() || zl == "nan" || zl == "-nan")
      z = std::numeric_limits<double>::quiet_NaN();
    else
      z = parse_decimal_scaled(f[1], *pz + 3);
    if (!z) fail_line(static_cast<int>(k + 1), "height \"" + f[1].substr(0, 30) + "\" is not a number");
    if (!xs.empty() && !(*x > xs.back()))
      fail_line(static_cast<int>(k + 1), fmt::format("lateral value {} does not increase (the previous is {})", f[0],
                                                     xs.back() * std::pow(10.0, -(*px + 3))));
    xs.push_back(*x), zs.push_back(*z);
    dec = std::max(dec, decimals(f[0]));
    if (xs.size() > kMaxSamples) fail_line(static_cast<int>(k + 1), "more samples than vmsim accepts");
  }
  if (xs.size() < 2) throw core::Error(name + ": fewer than 2 samples after the column header");
  // Least-squares line through (i, x_i): x0 and the spacing; the residuals against the printed rounding.
  const std::size_t n = xs.size();
  const double nm = static_cast<double>(n);
  double si = 0, sx = 0, sii = 0, six = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double di = static_cast<double>(i);
    si += di, sx += xs[i], sii += di * di, six += di * xs[i];
  }
  const double dx = (nm * six - si * sx) / (nm * sii - si * si);
  const double x0 = (sx - dx * si) / nm;
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(xs[i] - (x0 + dx * static_cast<double>(i))));
  const double half_digit = 0.5 * std::pow(10.0, -dec) * std::pow(10.0, *px + 3);  // mm
  DektakData out;
  out.profile.x0_mm = x0;
  out.profile.dx_mm = dx;
  out.profile.z_mm.resize(static_cast<Eigen::Index>(n));
  if (!(dx > 0)) throw core::Error(name + ": the lateral values do not increase");
  // The least-squares grid itself is uncertain by a fraction of the rounding (about digit / sqrt(n) at the ends):
  // values within 0.75 of a printed digit of it are taken as rounded grid positions.
  if (worst <= 1.5 * half_digit + 1e-12 * std::abs(x0 + dx * nm)) {
    for (std::size_t i = 0; i < n; ++i) out.profile.z_mm[static_cast<Eigen::Index>(i)] = zs[i];
    return out;
  }
  // Not a uniform grid within the rounding: linear resampling at the mean spacing from the first value.
  const double step = (xs.back() - xs.front()) / (nm - 1);
  out.profile.x0_mm = xs.front();
  out.profile.dx_mm = step;
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = xs.front() + step * static_cast<double>(i);
    while (j + 2 < n && xs[j + 1] < x) ++j;
    const double t = std::clamp((x - xs[j]) / (xs[j + 1] - xs[j]), 0.0, 1.0);
    out.profile.z_mm[static_cast<Eigen::Index>(i)] = (1 - t) * zs[j] + t * zs[j + 1];
  }
  out.note = fmt::format(
      "the lateral values depart from a uniform grid by up to {:.3g} um, more than their printed rounding "
      "({:.3g} um); the heights were resampled linearly every {:.6g} um",
      worst * 1e3, half_digit * 1e3, step * 1e3);
  return out;
}

DektakData read_dektak_csv(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return read_dektak_csv(ss.str(), file.string());
}

}  // namespace vmsim::metrology
