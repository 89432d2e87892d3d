#include "metrology/units.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <string>

namespace vmsim::metrology {

std::optional<double> parse_decimal_scaled(std::string_view s, int shift10) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  if (s.empty() || s.size() > 400) return std::nullopt;
  std::size_t i = 0;
  std::string mant;
  if (s[i] == '+' || s[i] == '-') mant += s[i++];
  std::size_t digits = 0;
  while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) mant += s[i++], ++digits;
  if (i < s.size() && s[i] == '.') {
    mant += s[i++];
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) mant += s[i++], ++digits;
  }
  if (digits == 0) return std::nullopt;
  long exp10 = 0;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    bool neg = false;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) neg = s[i++] == '-';
    std::size_t ed = 0;
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) {
      if (exp10 < 100000) exp10 = exp10 * 10 + (s[i] - '0');  // saturate: 1e100000 is inf or 0 anyway
      ++i, ++ed;
    }
    if (ed == 0) return std::nullopt;
    if (neg) exp10 = -exp10;
  }
  if (i != s.size()) return std::nullopt;
  const std::string text = mant + "e" + std::to_string(exp10 + shift10);
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return std::nullopt;
  return v;  // may be +-inf on overflow; callers check finiteness where they need it
}

std::string format_scaled(double v, int shift10) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "INF" : "-INF";
  if (v == 0) return std::signbit(v) ? "-0" : "0";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::scientific);
  std::string s(buf, r.ptr);
  const std::size_t e = s.find('e');
  const int exp10 = std::atoi(s.c_str() + e + 1) + shift10;
  s.erase(e);
  s += exp10 < 0 ? "E-" : "E+";
  const int a = std::abs(exp10);
  if (a < 10) s += '0';
  s += std::to_string(a);
  return s;
}

std::optional<int> length_unit_pow10(std::string_view u) {
  while (!u.empty() && (std::isspace(static_cast<unsigned char>(u.back())) || u.back() == '.')) u.remove_suffix(1);
  while (!u.empty() && std::isspace(static_cast<unsigned char>(u.front()))) u.remove_prefix(1);
  if (u == "m") return 0;
  if (u == "cm") return -2;
  if (u == "mm") return -3;
  if (u == "um" || u == "\xc2\xb5m" || u == "\xce\xbcm" || u == "\xb5m" || u == "micron" || u == "microns") return -6;
  if (u == "nm") return -9;
  if (u == "pm") return -12;
  if (u == "A" || u == "\xc3\x85" || u == "\xc5") return -10;
  return std::nullopt;
}

}  // namespace vmsim::metrology
