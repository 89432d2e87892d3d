#include "render/report_html.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "render/colormap.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <string_view>
#include <utility>
#include <vector>

namespace vmsim::render {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// ---- text ----------------------------------------------------------------------------------------------------------

// Every string that reaches the page goes through this: paths, job names, messages are user data.
std::string esc(std::string_view s) {
  std::string out;
  out.reserve(s.size() + 8);
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// A relative path inside the result directory as a URL path: bytes outside RFC 3986's unreserved set (and '/') are
// percent-encoded, so a file name with spaces or '#' still links to itself.
std::string url(std::string_view rel) {
  std::string out;
  for (const char ch : rel) {
    const auto c = static_cast<unsigned char>(ch);
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~' || c == '/') {
      out += static_cast<char>(c);
    } else {
      out += fmt::format("%{:02X}", c);
    }
  }
  return esc(out);
}

std::string num(double v, int significant = 4) {
  if (!std::isfinite(v)) return std::isnan(v) ? "NaN" : (v > 0 ? "∞" : "−∞");
  if (v == 0) return "0";
  std::string s = fmt::format("{:.{}g}", v, significant);
  if (s.front() == '-') s.replace(0, 1, "−");
  return s;
}

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return num(v);
  std::string s = fmt::format("{:.{}f}", v, decimals);
  if (s.front() == '-') s.replace(0, 1, "−");
  return s;
}

// A number from the report shown as text: the report's own value (its JSON text) stays machine-readable in a
// data-value attribute, so the page and report.json can be checked against each other. (Not HTML5's <data>
// element: Debian 12's tidy, one of the validators the tests use, does not know it yet.)
std::string data(const json& raw, const std::string& shown) {
  if (raw.is_number_float() && !std::isfinite(raw.get<double>()))
    return shown;  // JSON has no NaN: report.json says null
  return "<span data-value=\"" + esc(raw.dump()) + "\">" + shown + "</span>";
}

// Lengths stored in mm, shown in µm.
std::string um_from_mm(const json& v, int decimals = 2) {
  if (!v.is_number()) return "—";
  return data(v, fixed(v.get<double>() * 1e3, decimals) + " µm");
}
std::string um(const json& v, int decimals = 2) {
  if (!v.is_number()) return "—";
  return data(v, fixed(v.get<double>(), decimals) + " µm");
}
std::string mm(const json& v, int decimals = 3) {
  if (!v.is_number()) return "—";
  return data(v, fixed(v.get<double>(), decimals) + " mm");
}
std::string seconds(const json& v) {
  if (!v.is_number()) return "—";
  const double s = v.get<double>();
  return data(v, (std::abs(s) >= 100 ? fixed(s, 0) : std::abs(s) >= 1 ? fixed(s, 2) : num(s, 3)) + " s");
}
std::string percent(const json& v) {
  if (!v.is_number()) return "—";
  return data(v, fixed(v.get<double>(), 1) + " %");
}
std::string plain(const json& v, int significant = 6) {
  if (v.is_number_integer() || v.is_number_unsigned()) return data(v, v.dump());
  if (v.is_number()) return data(v, num(v.get<double>(), significant));
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_string()) return esc(v.get<std::string>());
  if (v.is_null()) return "—";
  return "<code>" + esc(v.dump()) + "</code>";
}

// "contour_error_max_um" -> "contour error max um": key names read as words in the tables.
std::string words(std::string_view key) {
  std::string s(key);
  std::replace(s.begin(), s.end(), '_', ' ');
  return esc(s);
}

const json* find(const json& j, std::string_view key) {
  if (!j.is_object()) return nullptr;
  const auto it = j.find(std::string(key));
  return it == j.end() ? nullptr : &*it;
}

const json& get(const json& j, std::initializer_list<std::string_view> path) {
  static const json none;
  const json* p = &j;
  for (const std::string_view k : path) {
    p = find(*p, k);
    if (!p) return none;
  }
  return *p;
}

// A key of an object, or null: the page reads a report of any shape (an older vmsim's, a hand-edited one) without
// throwing; what is missing or of another type is shown as "—" or as it is.
const json& at(const json& j, std::string_view key) {
  static const json none;
  const json* p = find(j, key);
  return p ? *p : none;
}

double number(const json& v, double fallback) { return v.is_number() ? v.get<double>() : fallback; }

std::string str(const json& v) { return v.is_string() ? v.get<std::string>() : std::string(); }

// ---- pictures ------------------------------------------------------------------------------------------------------

struct Picture {
  std::string rel;  // path relative to the result directory, '/' separated
  int width = 0, height = 0;
};

// A PNG's size from its IHDR chunk (the first chunk of every PNG, ISO/IEC 15948 section 11.2.2); nullopt when the
// file is not a PNG, so a broken file is never linked as a picture.
std::optional<std::pair<int, int>> png_size(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::array<unsigned char, 24> b{};
  if (!in.read(reinterpret_cast<char*>(b.data()), static_cast<std::streamsize>(b.size()))) return std::nullopt;
  static constexpr std::array<unsigned char, 8> sig = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!std::equal(sig.begin(), sig.end(), b.begin()) ||
      std::string_view(reinterpret_cast<const char*>(&b[12]), 4) != "IHDR")
    return std::nullopt;
  auto be32 = [&](std::size_t o) {
    return (std::uint32_t{b[o]} << 24) | (std::uint32_t{b[o + 1]} << 16) | (std::uint32_t{b[o + 2]} << 8) | b[o + 3];
  };
  const std::uint32_t w = be32(16), h = be32(20);
  if (w == 0 || h == 0 || w > 100000 || h > 100000) return std::nullopt;
  return std::make_pair(static_cast<int>(w), static_cast<int>(h));
}

// The PNG files of the directory's images/ folder, by name.
std::map<std::string, Picture> find_pictures(const fs::path& dir) {
  std::map<std::string, Picture> out;
  std::error_code ec;
  const fs::path idir = dir / "images";
  if (!fs::is_directory(idir, ec)) return out;
  for (const auto& e : fs::directory_iterator(idir, ec)) {
    if (!e.is_regular_file(ec) || e.path().extension() != ".png") continue;
    if (const auto size = png_size(e.path())) {
      const std::string rel = "images/" + e.path().filename().string();
      out[rel] = {rel, size->first, size->second};
    }
  }
  return out;
}

// ---- the page ------------------------------------------------------------------------------------------------------

constexpr std::string_view kStyle = R"css(
:root{--fg:#1b1f24;--muted:#5a6270;--line:#d5d9e0;--alt:#f3f5f8;--accent:#1f4e8c;--warn:#9a5b00;--warnbg:#fff5e0;--bad:#a11d1d;--badbg:#fdecec;--good:#1d6b33;--goodbg:#e8f5ec}
*{box-sizing:border-box}
html{-webkit-text-size-adjust:100%;text-size-adjust:100%}
body{margin:0;color:var(--fg);background:#fff;font:15px/1.45 "DejaVu Sans",system-ui,-apple-system,"Segoe UI",Roboto,sans-serif}
header,main,footer{max-width:1180px;margin:0 auto;padding:0 16px}
header{padding-top:12px}
h1{font-size:1.55em;margin:.3em 0 .1em;overflow-wrap:anywhere}
h2{font-size:1.2em;margin:1.6em 0 .5em;padding-bottom:.15em;border-bottom:2px solid var(--accent)}
h3{font-size:1.02em;margin:1.2em 0 .4em}
.sub{color:var(--muted);margin:0}
nav{margin:.8em 0;font-size:.93em}
nav ul{list-style:none;padding:0;margin:0;display:flex;flex-wrap:wrap;gap:.25em 1.1em}
a{color:var(--accent)}
.scroll{overflow-x:auto;max-width:100%;margin:.4em 0}
table{border-collapse:collapse;font-variant-numeric:tabular-nums}
caption{text-align:left;color:var(--muted);font-size:.9em;padding:.2em 0}
th,td{border:1px solid var(--line);padding:3px 8px;text-align:left;vertical-align:top}
thead th{background:var(--alt);white-space:nowrap}
tbody th{background:var(--alt);font-weight:normal}
td.n{text-align:right;white-space:nowrap}
table.kv td:first-child{color:var(--muted)}
td table{margin:0;font-size:.92em}
.hash,code{font-family:"DejaVu Sans Mono",ui-monospace,monospace;font-size:.86em;overflow-wrap:anywhere}
.path{overflow-wrap:anywhere}
.kpi{display:grid;grid-template-columns:repeat(auto-fill,minmax(160px,1fr));gap:8px;margin:.6em 0}
.kpi div{background:var(--alt);border-radius:4px;padding:8px 10px}
.kpi b{display:block;font-size:1.25em}
.kpi span{color:var(--muted);font-size:.88em}
.figs{display:grid;grid-template-columns:repeat(auto-fill,minmax(min(100%,440px),1fr));gap:16px;align-items:start}
figure{margin:.6em 0}
figure img{display:block;max-width:100%;height:auto;border:1px solid var(--line);background:#fff}
figcaption{color:var(--muted);font-size:.88em;margin-top:.3em}
.note{border-left:4px solid var(--warn);background:var(--warnbg);padding:8px 12px;margin:.8em 0}
.verdict{border-left:6px solid var(--accent);background:var(--alt);padding:10px 14px;margin:.8em 0}
.verdict.ok{border-color:var(--good);background:var(--goodbg)}
.verdict.bad{border-color:var(--bad);background:var(--badbg)}
.verdict.warn{border-color:var(--warn);background:var(--warnbg)}
ul.warnings{padding-left:1.2em}
.scale{max-width:520px;margin:.5em 0 1em}
.scale .bar{height:14px;border:1px solid var(--line)}
.scale .ticks{display:flex;justify-content:space-between;font-size:.85em;color:var(--muted)}
footer{color:var(--muted);font-size:.85em;margin:2em auto 1.5em}
@media (max-width:600px){body{font-size:14px}th,td{padding:2px 5px}h1{font-size:1.3em}}
@media print{
 body{font-size:10pt}
 nav,footer .noprint{display:none}
 a{color:inherit;text-decoration:none}
 header,main,footer{max-width:none;padding:0}
 h2{break-after:avoid}
 figure,tr,.kpi div,.verdict,.note{break-inside:avoid}
 .scroll{overflow:visible}
 .figs{display:block}
 figure img{max-height:120mm;width:auto}
 @page{margin:14mm}
}
)css";

class Page {
 public:
  Page(const json& report, const fs::path& dir) : r_(report), dir_(dir), pictures_(find_pictures(dir)) {}

  // Keys of the report a section has shown (top level, or "a/b" one level down): left out of "All figures".
  void shown(const std::string& key) { shown_.insert(key); }

  void section(const std::string& id, const std::string& title, const std::string& html) {
    if (html.empty()) return;
    toc_.emplace_back(id, title);
    body_ += "<section id=\"" + esc(id) + "\">\n<h2>" + esc(title) + "</h2>\n" + html + "</section>\n";
  }

  bool has_picture(const std::string& rel) const { return pictures_.count(rel) > 0; }

  // <figure> for a picture of the directory, or "" when it is absent; each picture is placed once.
  std::string figure(const std::string& rel, const std::string& caption) {
    const auto it = pictures_.find(rel);
    if (it == pictures_.end() || placed_.count(rel)) return "";
    placed_.insert(rel);
    const Picture& p = it->second;
    return "<figure><a href=\"" + url(p.rel) + "\"><img src=\"" + url(p.rel) + "\" width=\"" + std::to_string(p.width) +
           "\" height=\"" + std::to_string(p.height) + "\" alt=\"" + esc(caption) + "\"></a><figcaption>" +
           esc(caption) + " <span class=\"path\">(" + esc(p.rel) + ")</span></figcaption></figure>\n";
  }
  std::string figures(const std::vector<std::pair<std::string, std::string>>& list) {
    std::string s;
    for (const auto& [rel, caption] : list) s += figure(rel, caption);
    return s.empty() ? "" : "<div class=\"figs\">\n" + s + "</div>\n";
  }
  // Pictures of the directory that no section placed, in name order.
  std::string other_figures() {
    std::vector<std::pair<std::string, std::string>> rest;
    for (const auto& [rel, p] : pictures_)
      if (!placed_.count(rel)) rest.emplace_back(rel, fs::path(rel).stem().string());
    return figures(rest);
  }
  std::size_t picture_count() const { return pictures_.size(); }

  const json& report() const { return r_; }
  const fs::path& dir() const { return dir_; }
  const std::set<std::string>& shown_keys() const { return shown_; }

  std::string html(const std::string& title, const std::string& subtitle) const {
    std::string s;
    s.reserve(body_.size() + 8192);
    s += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
         "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
         "<meta name=\"generator\" content=\"vmsim\">\n<title>" +
         esc(title) + "</title>\n<style>" + std::string(kStyle) + "</style>\n</head>\n<body>\n<header>\n<h1>" +
         esc(title) + "</h1>\n<p class=\"sub\">" + subtitle + "</p>\n<nav aria-label=\"sections\"><ul>";
    for (const auto& [id, t] : toc_) s += "<li><a href=\"#" + esc(id) + "\">" + esc(t) + "</a></li>";
    s += "</ul></nav>\n</header>\n<main>\n" + body_ + "</main>\n<footer><p>Generated by vmsim from <a href=\"" +
         url(source_name()) + "\">" + esc(source_name()) +
         "</a> and the files of this folder; every figure on this page is in that "
         "file.</p></footer>\n</body>\n</html>\n";
    return s;
  }

  std::string source_name() const { return str(at(r_, "command")) == "study" ? "study.json" : "report.json"; }

 private:
  const json& r_;
  fs::path dir_;
  std::map<std::string, Picture> pictures_;
  std::set<std::string> placed_, shown_;
  std::vector<std::pair<std::string, std::string>> toc_;
  std::string body_;
};

// ---- building blocks -----------------------------------------------------------------------------------------------

std::string table(const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows,
                  const std::vector<bool>& numeric = {}, const std::string& cls = "") {
  std::string s = "<div class=\"scroll\"><table" + (cls.empty() ? "" : " class=\"" + cls + "\"") + ">";
  if (!head.empty()) {
    s += "<thead><tr>";
    for (const auto& h : head) s += "<th>" + h + "</th>";
    s += "</tr></thead>";
  }
  s += "<tbody>";
  for (const auto& row : rows) {
    s += "<tr>";
    for (std::size_t c = 0; c < row.size(); ++c)
      s += (c < numeric.size() && numeric[c] ? "<td class=\"n\">" : "<td>") + row[c] + "</td>";
    s += "</tr>";
  }
  return s + "</tbody></table></div>\n";
}

std::string kpi(const std::vector<std::pair<std::string, std::string>>& items) {
  std::string s;
  for (const auto& [value, label] : items)
    if (!value.empty()) s += "<div><b>" + value + "</b><span>" + label + "</span></div>";
  return s.empty() ? "" : "<div class=\"kpi\">" + s + "</div>\n";
}

bool scalar(const json& v) { return !v.is_object() && !v.is_array(); }

std::string value_html(const json& v);

// An array of objects as a table: one row per element, one column per key met (in order of first appearance).
std::string object_table(const json& arr) {
  std::vector<std::string> keys;
  for (const auto& e : arr)
    for (const auto& [k, x] : e.items())
      if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
  std::vector<std::string> head;
  for (const auto& k : keys) head.push_back(words(k));
  std::vector<std::vector<std::string>> rows;
  std::vector<bool> numeric(keys.size(), true);
  for (const auto& e : arr) {
    std::vector<std::string> row;
    for (std::size_t c = 0; c < keys.size(); ++c) {
      const json* x = find(e, keys[c]);
      if (x && !x->is_number() && !x->is_null()) numeric[c] = false;
      row.push_back(x ? value_html(*x) : "");
    }
    rows.push_back(row);
  }
  return table(head, rows, numeric);
}

bool all_objects(const json& arr) {
  return arr.is_array() && !arr.empty() &&
         std::all_of(arr.begin(), arr.end(), [](const json& e) { return e.is_object(); });
}

// Any JSON value, readable: scalars as text, lists of scalars comma-separated, lists of objects as tables, objects
// as key/value tables.
std::string value_html(const json& v) {
  if (scalar(v)) return plain(v);
  if (all_objects(v)) return object_table(v);
  if (v.is_object() && !v.empty() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_object(); })) {
    // An object of objects (per axis, per run): one row each, its name first.
    json rows = json::array();
    for (const auto& [k, x] : v.items()) {
      json row = {{"", k}};
      for (const auto& [k2, x2] : x.items()) row[k2] = x2;
      rows.push_back(row);
    }
    return object_table(rows);
  }
  if (v.is_array()) {
    std::string s;
    for (const auto& e : v) s += (s.empty() ? "" : ", ") + (scalar(e) ? plain(e) : value_html(e));
    return v.empty() ? "(none)" : s;
  }
  if (v.empty()) return "(none)";
  std::vector<std::vector<std::string>> rows;
  for (const auto& [k, x] : v.items()) rows.push_back({words(k), value_html(x)});
  return table({}, rows, {false, false}, "kv");
}

// An object's entries flattened to rows "a › b › c | value" (lists of objects stay whole, as a table in the cell).
void flatten(const json& v, const std::string& prefix, std::vector<std::vector<std::string>>& rows) {
  if (v.is_object() && !v.empty()) {
    for (const auto& [k, x] : v.items()) flatten(x, prefix.empty() ? words(k) : prefix + " › " + words(k), rows);
    return;
  }
  rows.push_back({prefix, value_html(v)});
}

std::string kv_table(const json& obj, const std::set<std::string>& skip = {}) {
  std::vector<std::vector<std::string>> rows;
  if (!obj.is_object()) return "";
  for (const auto& [k, x] : obj.items())
    if (!skip.count(k)) flatten(x, words(k), rows);
  return rows.empty() ? "" : table({}, rows, {false, false}, "kv");
}

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

// A key and its value, where lengths in mm are better read in µm (deviations, contour errors): "max_mm" reads
// "max" with its value in µm when `um_decimals` >= 0.
std::pair<std::string, std::string> entry(const std::string& key, const json& v, int um_decimals) {
  if (um_decimals >= 0 && ends_with(key, "_mm") && v.is_number())
    return {words(key.substr(0, key.size() - 3)), um_from_mm(v, um_decimals)};
  return {words(key), value_html(v)};
}

// An object's leaves in order, nested objects' keys joined: {"check": {"feed": 1}} -> ("check", "feed"), 1.
void leaves(const json& v, const std::vector<std::string>& path,
            std::vector<std::pair<std::vector<std::string>, const json*>>& out) {
  if (v.is_object() && !v.empty()) {
    for (const auto& [k, x] : v.items()) {
      std::vector<std::string> p = path;
      p.push_back(k);
      leaves(x, p, out);
    }
    return;
  }
  out.emplace_back(path, &v);
}

// Several objects of the same kind side by side: one row per leaf key (in the order met), one column per object.
std::string side_by_side(const std::vector<std::pair<std::string, const json*>>& cols, int um_decimals = -1) {
  std::vector<std::vector<std::string>> keys;
  std::vector<std::map<std::vector<std::string>, const json*>> values(cols.size());
  for (std::size_t c = 0; c < cols.size(); ++c) {
    if (!cols[c].second || !cols[c].second->is_object()) continue;
    std::vector<std::pair<std::vector<std::string>, const json*>> l;
    leaves(*cols[c].second, {}, l);
    for (const auto& [path, x] : l) {
      if (std::find(keys.begin(), keys.end(), path) == keys.end()) keys.push_back(path);
      values[c][path] = x;
    }
  }
  if (keys.empty()) return "";
  std::vector<std::string> head = {""};
  for (const auto& [name, obj] : cols) head.push_back(esc(name));
  std::vector<std::vector<std::string>> rows;
  for (const auto& path : keys) {
    std::string label;
    for (std::size_t i = 0; i + 1 < path.size(); ++i) label += words(path[i]) + " › ";
    label += entry(path.back(), json(0.0), um_decimals).first;
    std::vector<std::string> row = {label};
    for (std::size_t c = 0; c < cols.size(); ++c) {
      const auto it = values[c].find(path);
      row.push_back(it == values[c].end() ? "" : entry(path.back(), *it->second, um_decimals).second);
    }
    rows.push_back(row);
  }
  std::vector<bool> numeric(head.size(), true);
  numeric[0] = false;
  return table(head, rows, numeric);
}

// An object whose entries are objects of one kind (limits and the peaks held against them, original and
// compensated): those side by side, the other entries as a key/value table.
std::string grouped(const json& obj, int um_decimals = -1) {
  if (!obj.is_object()) return value_html(obj);
  std::vector<std::pair<std::string, const json*>> cols;
  std::set<std::string> in_cols;
  for (const auto& [k, x] : obj.items())
    if (x.is_object() && !x.empty()) cols.emplace_back(k, &x), in_cols.insert(k);
  if (cols.size() < 2) return kv_table(obj);
  std::string s;
  std::vector<std::pair<std::string, const json*>> labelled;
  for (const auto& [k, x] : cols) {
    std::string l = k;
    std::replace(l.begin(), l.end(), '_', ' ');
    labelled.emplace_back(l, x);
  }
  s += side_by_side(labelled, um_decimals);
  std::vector<std::vector<std::string>> rows;
  for (const auto& [k, x] : obj.items())
    if (!in_cols.count(k)) flatten(x, words(k), rows);
  if (!rows.empty()) s += table({}, rows, {false, false}, "kv");
  return s;
}

// An object's scalar entries as a key/value table, lengths in µm (see entry()); other entries flattened as usual.
std::string kv_table_um(const json& obj, int um_decimals, const std::set<std::string>& skip = {}) {
  std::vector<std::vector<std::string>> rows;
  if (!obj.is_object()) return "";
  for (const auto& [k, x] : obj.items()) {
    if (skip.count(k)) continue;
    if (x.is_object()) {
      flatten(x, words(k), rows);
    } else {
      const auto [key, value] = entry(k, x, um_decimals);
      rows.push_back({key, value});
    }
  }
  return rows.empty() ? "" : table({}, rows, {false, false}, "kv");
}

// ---- sections shared by every command ------------------------------------------------------------------------------

std::string verdict_html(Page& p) {
  const json& r = p.report();
  std::string s;
  if (const json* v = find(r, "verdict")) {
    p.shown("verdict");
    // The verdict's form is not fixed here: a sentence, or an object whose "status"/"level" colours the box.
    std::string cls, text;
    if (v->is_string()) {
      text = esc(v->get<std::string>());
    } else if (v->is_object()) {
      const std::string status = str(at(*v, "status").is_null() ? at(*v, "level") : at(*v, "status"));
      if (status == "ok" || status == "pass" || status == "good") cls = " ok";
      if (status == "warn" || status == "warning" || status == "marginal") cls = " warn";
      if (status == "fail" || status == "bad" || status == "error" || status == "reject") cls = " bad";
      text = kv_table(*v);
    } else {
      text = plain(*v);
    }
    s += "<div class=\"verdict" + cls + "\">" + text + "</div>\n";
  }
  if (const json* w = find(r, "warnings")) {
    p.shown("warnings");
    if (w->is_array() && !w->empty()) {
      s += "<ul class=\"warnings\">";
      for (const auto& e : *w) {
        if (e.is_string())
          s += "<li>" + esc(e.get<std::string>()) + "</li>";
        else if (e.is_object() && e.contains("message") && e.size() == 1)
          s += "<li>" + plain(e["message"]) + "</li>";
        else
          s += "<li>" + value_html(e) + "</li>";
      }
      s += "</ul>\n";
    } else if (w->is_array()) {
      s += "<p>No warnings.</p>\n";
    } else {
      s += "<p>" + value_html(*w) + "</p>\n";
    }
  }
  return s;
}

std::string inputs_html(Page& p) {
  const json& in = get(p.report(), {"inputs"});
  if (!in.is_object() || in.empty()) return "";
  p.shown("inputs");
  std::vector<std::vector<std::string>> rows;
  for (const auto& [role, f] : in.items()) {
    if (f.is_object()) {
      rows.push_back(
          {words(role), "<span class=\"path\">" + esc(str(at(f, "path"))) + "</span>",
           "<span class=\"hash\">" + (at(f, "sha256").is_string() ? esc(str(at(f, "sha256"))) : "—") + "</span>"});
      for (const auto& [k, x] : f.items())
        if (k != "path" && k != "sha256") rows.back()[1] += "<br>" + words(k) + ": " + value_html(x);
    } else {
      rows.push_back({words(role), value_html(f), ""});
    }
  }
  return table({"input", "file", "SHA-256"}, rows);
}

std::string timings_html(Page& p) {
  const json& t = get(p.report(), {"timings_s"});
  if (!t.is_object() || t.empty()) return "";
  p.shown("timings_s");
  std::vector<std::vector<std::string>> rows;
  for (const auto& [k, x] : t.items())
    if (k != "total") rows.push_back({words(k), x.is_number() ? seconds(x) : value_html(x)});
  if (const json* total = find(t, "total")) rows.push_back({"<b>total</b>", "<b>" + seconds(*total) + "</b>"});
  return "<p>Wall-clock time of each stage, in seconds (CPU times where a key says so).</p>\n" +
         table({"stage", "time"}, rows, {false, true});
}

std::string files_html(Page& p) {
  std::vector<std::string> names;
  for (const char* key : {"files", "images"}) {  // oga and plan-feed list their pictures apart
    const json& list = get(p.report(), {key});
    if (list.is_array() && std::all_of(list.begin(), list.end(), [](const json& e) { return e.is_string(); })) {
      p.shown(key);
      for (const auto& e : list)
        if (std::find(names.begin(), names.end(), e.get<std::string>()) == names.end())
          names.push_back(e.get<std::string>());
    }
  }
  if (str(at(p.report(), "command")) == "study") names.push_back("results.csv");
  const std::string self = p.source_name();
  if (std::find(names.begin(), names.end(), self) == names.end()) names.push_back(self);
  std::string s = "<ul>";
  for (const auto& n : names) {
    std::error_code ec;
    // Only names inside the folder become links: the page travels with its folder.
    const bool inside = !n.empty() && n.front() != '/' && n.find("..") == std::string::npos;
    if (inside && fs::exists(p.dir() / n, ec))
      s += "<li><a href=\"" + url(n) + "\">" + esc(n) + "</a></li>";
    else
      s += "<li>" + esc(n) + (inside ? " (not in this folder)" : "") + "</li>";
  }
  return s + "</ul>\n";
}

// Why a page has no pictures: the error the command met drawing them, or that it was asked for none (`draws`: the
// command draws pictures unless --no-render; `hint`: how to get them afterwards).
std::string pictures_note(Page& p, bool draws, const std::string& hint = "") {
  const json& r = p.report();
  std::string why;
  if (const json* e = find(r, "render_error")) {
    p.shown("render_error");
    why = p.picture_count() == 0 ? "The pictures could not be drawn: " + plain(*e)
                                 : "When the command ran, the pictures could not be drawn (" + plain(*e) +
                                       "); those shown were drawn afterwards.";
  } else if (const json* e2 = find(get(r, {"pictures"}), "error")) {
    why = "The pictures could not be drawn: " + plain(*e2);
  } else if (p.picture_count() == 0 && draws) {
    why = "This folder holds no pictures: the command was run with --no-render." + (hint.empty() ? "" : " " + hint);
  }
  if (why.empty()) return "";
  return "<p class=\"note\">" + why + " Every other figure is on this page.</p>\n";
}

// The colour scale of the deviation pictures (render/colormap: the same function draws the pictures' colours).
std::string colour_scale(const json& limit) {
  const double limit_um = number(limit, NAN);
  std::string stops;
  for (int k = 0; k <= 10; ++k) {
    const Rgb c = diverging_colour(-1.0 + 0.2 * k);
    stops += fmt::format("{}rgb({},{},{}) {}%", k ? "," : "", std::lround(c[0] * 255), std::lround(c[1] * 255),
                         std::lround(c[2] * 255), k * 10);
  }
  return "<div class=\"scale\"><div class=\"bar\" style=\"background:linear-gradient(to right," + stops +
         ")\"></div><div class=\"ticks\"><span>−" + num(limit_um) + " µm (overcut)</span><span>0</span><span>+" +
         data(limit, num(limit_um)) + " µm (undercut: material left)</span></div></div>\n";
}

// "All figures": every key no section showed, flattened; nothing in report.json is hidden.
std::string rest_html(Page& p, const std::set<std::string>& always_skip = {}) {
  const json& r = p.report();
  std::vector<std::vector<std::string>> rows;
  std::string per_item;  // objects of objects (per axis, per run): one table each, the objects side by side
  for (const auto& [k, x] : r.items()) {
    if (always_skip.count(k)) continue;
    if (p.shown_keys().count(k)) continue;
    if (x.is_object() && x.size() >= 2 &&
        std::all_of(x.begin(), x.end(), [](const json& e) { return e.is_object() && !e.empty(); })) {
      per_item += "<h3>" + words(k) + "</h3>\n" + grouped(x);
    } else if (x.is_object()) {
      for (const auto& [k2, x2] : x.items())
        if (!p.shown_keys().count(k + "/" + k2)) flatten(x2, words(k) + " › " + words(k2), rows);
    } else {
      flatten(x, words(k), rows);
    }
  }
  if (rows.empty() && per_item.empty()) return "";
  return "<p>Every other entry of " + esc(p.source_name()) +
         ", as written (key names carry their units: _mm, _um, _s, _deg, _mm_per_s, ...).</p>\n" +
         (rows.empty() ? "" : table({"key", "value"}, rows, {false, false}, "kv")) + per_item;
}

// The marks as `vmsim run` and `vmsim compare` write them.
std::string marks_table(const json& marks) {
  std::vector<std::vector<std::string>> rows;
  bool along = false, extent = false, area = false, width = false, vertical = false, tool = false;
  for (const auto& m : marks) {
    tool |= m.contains("tool");
    along |= m.contains("along_mm") || m.contains("along_path_mm");
    width |= m.contains("width_mm");
    extent |= m.contains("x_extent_mm");
    area |= m.contains("area_mm2");
    vertical |= m.contains("depth_vertical_mm");
  }
  // vmsim run's depth is along the reference's normal; its vertical depth and the slope there beside it.
  std::vector<std::string> head = {"#", "kind", vertical ? "depth (normal)" : "depth", "x", "y"};
  if (vertical) head.insert(head.end(), {"depth (vertical)", "slope"});
  if (extent) head.insert(head.end(), {"extent x", "extent y"});
  if (width) head.push_back("width across the path");
  if (along) head.push_back("length along the path");
  if (area) head.push_back("area");
  if (tool) head.push_back("tool");
  std::vector<bool> numeric(head.size(), true);
  numeric[1] = false;
  if (tool) numeric.back() = false;
  int k = 0;
  for (const auto& m : marks) {
    std::vector<std::string> row = {std::to_string(++k), plain(at(m, "kind")), um_from_mm(at(m, "depth_mm")),
                                    mm(at(m, "x_mm")), mm(at(m, "y_mm"))};
    if (vertical)
      row.insert(row.end(), {um_from_mm(at(m, "depth_vertical_mm")),
                             at(m, "slope_deg").is_number()
                                 ? data(m["slope_deg"], num(m["slope_deg"].get<double>(), 3) + "°" +
                                                            (at(m, "steep_wall") == json(true) ? " (steep wall)" : ""))
                                 : plain(at(m, "slope_deg"))});
    if (extent) row.insert(row.end(), {mm(at(m, "x_extent_mm")), mm(at(m, "y_extent_mm"))});
    if (width) row.push_back(mm(at(m, "width_mm")));
    if (along) row.push_back(mm(at(m, "along_mm").is_null() ? at(m, "along_path_mm") : at(m, "along_mm")));
    if (area)
      row.push_back(at(m, "area_mm2").is_number() ? data(m["area_mm2"], num(m["area_mm2"].get<double>(), 4) + " mm²")
                                                  : plain(at(m, "area_mm2")));
    if (tool) row.push_back(plain(at(m, "tool")));
    rows.push_back(row);
  }
  return table(head, rows, numeric);
}

std::string deepest_mark_kpi(const json& marks) {
  if (!marks.is_array() || marks.empty()) return "";
  const json& m = marks.front();
  return um_from_mm(at(m, "depth_mm"));
}

std::string mark_label(const json& marks, bool have_reference) {
  if (!marks.is_array()) return "";
  if (marks.empty()) return have_reference ? "no mark deeper than 1 µm" : "";
  const json& m = marks.front();
  return "deepest mark, " + esc(str(at(m, "kind"))) + " at x " + fixed(number(at(m, "x_mm"), NAN), 2) + ", y " +
         fixed(number(at(m, "y_mm"), NAN), 2) + " mm";
}

// ---- per command ---------------------------------------------------------------------------------------------------

// The charts of a run's drive signals, in reading order: contour error and feed, then each axis.
void motion_charts(Page& p) {
  std::vector<std::pair<std::string, std::string>> list = {
      {"images/contour_error.png", "Signed contour error on cutting moves along the cutting path, µm"},
      {"images/feed.png",
       "Programmed feed (× feed scale), the setpoints' path speed and the actual tool-tip speed, mm/min"}};
  std::string s = p.figures(list);
  std::vector<std::pair<std::string, std::string>> axes;
  for (const std::string prefix : {"images/position_", "images/axis_"}) {
    std::error_code ec;
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(p.dir() / "images", ec)) {
      const std::string rel = "images/" + e.path().filename().string();
      if (rel.rfind(prefix, 0) == 0 && p.has_picture(rel)) names.push_back(rel);
    }
    std::sort(names.begin(), names.end());
    for (const auto& n : names) {
      const std::string axis = fs::path(n).stem().string().substr(fs::path(prefix).filename().string().size());
      axes.emplace_back(n, prefix == "images/position_"
                               ? "Axis " + axis + ": setpoint and actual position, and the tracking error in µm"
                               : "Axis " + axis +
                                     ": velocity, acceleration and jerk of the setpoints and drives, "
                                     "with the machine file's limits");
    }
  }
  axes.emplace_back("images/currents.png", "Motor currents (mean and peak per Te) with the drives' current limit");
  s += p.figures(axes);
  p.section("motion", "Contour error, feed and axes", s);
}

// report.json "tools": which tool cut what (issue 24), one row per tool.
void tools_section(Page& p) {
  const json& tools = get(p.report(), {"tools", "list"});
  if (!tools.is_array() || tools.empty()) return;
  p.shown("tools");
  bool timed = false, numbered = false, mapped = false;
  for (const auto& t : tools)
    timed |= t.contains("time_s"), numbered |= t.contains("number"), mapped |= t.contains("last_cut_area_mm2");
  std::vector<std::string> head = {"tool",   "type",       "diameter", "corner radius", "flute length",
                                   "length", "moves",      "feed moves", "sweeps"};
  if (timed) head.push_back("time");
  if (numbered) head.push_back("T number");
  if (mapped) head.push_back("last cut area");
  std::vector<bool> numeric(head.size(), true);
  numeric[0] = numeric[1] = false;
  std::vector<std::vector<std::string>> rows;
  for (const auto& t : tools) {
    std::vector<std::string> row = {plain(at(t, "tool")),        plain(at(t, "type")),         mm(at(t, "diameter_mm")),
                                    mm(at(t, "corner_radius_mm")), mm(at(t, "flute_length_mm")), mm(at(t, "length_mm")),
                                    plain(at(t, "moves")),       plain(at(t, "feed_moves")),   plain(at(t, "sweeps"))};
    if (timed) row.push_back(seconds(at(t, "time_s")));
    if (numbered) row.push_back(plain(at(t, "number")));
    if (mapped) row.push_back(plain(at(t, "last_cut_area_mm2")) + " mm²");
    rows.push_back(row);
  }
  p.section(
      "tools", "Tools",
      "<p>The tools that cut, from " + plain(get(p.report(), {"tools", "source"})) +
          ": each move is cut by the tool in the spindle; time is on the setpoints. A mark's tool is the one "
          "whose sweep made the surface at its deepest point." +
          (mapped ? " Last cut area: the part's surface (from above) where the tool was the last to cut." : "") +
          "</p>\n" + table(head, rows, numeric) +
          p.figures({{"images/tools.png", "Which tool cut where: each point coloured by the last tool that cut it"}}));
}

void run_page(Page& p) {
  const json& r = p.report();
  const json& marks = get(r, {"marks"});
  const bool have_ref = str(at(r, "reference")) != "none" && find(r, "reference");
  const json& ce = get(r, {"contour_error", "cutting_moves"});
  const json& cycle = get(r, {"interpolation", "cycle_time_s"});
  const json& surf = get(r, {"surface"});

  std::string summary = verdict_html(p);
  const double lo = get(surf, {"deviation_min_mm"}).is_number() ? surf["deviation_min_mm"].get<double>() : NAN;
  const double hi = get(surf, {"deviation_max_mm"}).is_number() ? surf["deviation_max_mm"].get<double>() : NAN;
  summary += kpi({
      {marks.is_array() && !marks.empty() ? deepest_mark_kpi(marks) : (marks.is_array() && have_ref ? "none" : ""),
       mark_label(marks, have_ref)},
      {marks.is_array() ? data(json(marks.size()), std::to_string(marks.size())) : "", "marks deeper than 1 µm"},
      {ce.is_object() ? um_from_mm(at(ce, "max_abs_mm")) : "", "contour error max, cutting moves"},
      {ce.is_object() ? um_from_mm(at(ce, "rms_mm")) : "", "contour error RMS, cutting moves"},
      {cycle.is_number() ? seconds(cycle) : "", "cycle time"},
      {std::isfinite(lo) ? um_from_mm(surf["deviation_min_mm"]) + " … " + um_from_mm(surf["deviation_max_mm"]) : "",
       "deviation range (negative: overcut)"},
      {seconds(get(r, {"timings_s", "total"})), "run time"},
  });
  if (find(r, "reference")) {
    summary += "<p>Marks and deviation are measured against: <b>" + plain(r["reference"]) + "</b>.</p>\n";
    p.shown("reference");
  }
  summary += pictures_note(p, true, "<code>vmsim render DIR</code> draws them from the result files.");
  p.section("summary", "Summary", summary);
  p.section("inputs", "Job and inputs", inputs_html(p));

  p.section(
      "part", "Part",
      p.figures({{"images/part.png", "The whole part, isometric, under a raking light from the left"},
                 {"images/part_mark.png",
                  "The deepest mark seen along the path, its departure from the "
                  "reference magnified (the form true to scale)"},
                 {"images/deviation_3d.png", "The zoomed part coloured by its deviation under the raking light"}}));

  if (marks.is_array()) {
    p.shown("marks");
    std::string s;
    if (marks.empty()) {
      s = have_ref ? "<p>No mark deeper than 1 µm.</p>\n" : "<p>No reference surface: no marks are measured.</p>\n";
    } else {
      s = "<p>Regions where the predicted surface departs from the reference by more than 1 µm, deepest first "
          "(overcut: below the reference; undercut: material left). Place: the deepest point; extent: the region's "
          "size in x and y.</p>\n" +
          marks_table(marks);
      s += p.figures({{"images/deviation_mark.png", "Mark 1: the deviation map zoomed on the deepest mark"}});
    }
    p.section("marks", "Marks", s);
  }
  tools_section(p);

  std::string dev;
  if (std::isfinite(lo) && std::isfinite(hi)) {
    const std::array<double, 2> v = {lo * 1e3, hi * 1e3};
    // The pictures' own limits: the same function, on the same extremes (unless `vmsim render --limit-um` redrew them).
    const double limit_um = symmetric_limit(v, 1.0);
    dev += p.figure("images/deviation.png", "The deviation map of the whole part, from above at true scale") +
           (p.has_picture("images/deviation.png") || p.has_picture("images/deviation_mark.png")
                ? colour_scale(json(limit_um))
                : "");
    const bool normal = get(surf, {"deviation_along"}) == json("normal");
    dev += std::string("<p>Deviation = predicted − reference") +
           (normal ? " along the reference surface's normal (vertically: from " +
                         um_from_mm(surf["deviation_vertical_min_mm"]) + " to " +
                         um_from_mm(surf["deviation_vertical_max_mm"]) + ")"
                   : std::string()) +
           ": from " + um_from_mm(surf["deviation_min_mm"]) + " to " + um_from_mm(surf["deviation_max_mm"]) +
           ". Colour limits ±" + num(limit_um) +
           " µm: the largest |deviation| rounded up to 1, 2, 2.5 or 5 × 10^k.</p>\n";
  }
  p.section("deviation", "Deviation map", dev);
  motion_charts(p);

  std::string removal;
  if (const json* rm = find(r, "removal")) {
    p.shown("removal");
    removal += kv_table(*rm);
  }
  if (surf.is_object()) {
    p.shown("surface");
    removal += "<h3>Surface</h3>\n" + kv_table(surf);
  }
  p.section("removal", "Material removal and surface", removal);

  std::string motion;
  if (ce.is_object()) {
    p.shown("contour_error");
    motion += "<h3>Contour error</h3>\n" +
              side_by_side({{"cutting moves", &ce}, {"all moves", &get(r, {"contour_error", "all_moves"})}}, 2);
  }
  if (const json* ip = find(r, "interpolation")) {
    p.shown("interpolation");
    motion += "<h3>Interpolation</h3>\n" + kv_table(*ip);
  }
  if (const json* af = find(r, "axis_following_error")) {
    p.shown("axis_following_error");
    motion += "<h3>Following error per axis</h3>\n" + value_html(*af);
  }
  p.section("figures-motion", "Motion figures", motion);
}

void compare_page(Page& p) {
  const json& r = p.report();
  const json& marks = get(r, {"marks", "list"});
  const json& reg = get(r, {"registration"});
  const json& dev = get(r, {"deviation"});
  std::string summary = verdict_html(p);
  summary += kpi({
      {marks.is_array() && !marks.empty() ? deepest_mark_kpi(marks) : (marks.is_array() ? "none" : ""),
       marks.is_array() && !marks.empty() ? mark_label(marks, true) : "marks above the threshold"},
      {marks.is_array() ? data(json(marks.size()), std::to_string(marks.size())) : "", "marks"},
      {reg.is_object() ? um_from_mm(at(reg, "residual_rms_mm")) : "", "registration residual RMS"},
      {um_from_mm(get(dev, {"rms_mm"})), "deviation RMS"},
      {dev.is_object() ? um_from_mm(get(dev, {"min_mm"})) + " … " + um_from_mm(get(dev, {"max_mm"})) : "",
       "deviation range, measured − predicted"},
      {seconds(get(r, {"timings_s", "total"})), "run time"},
  });
  summary += pictures_note(p, true);
  p.section("summary", "Summary", summary);
  p.section("inputs", "Inputs", inputs_html(p));
  for (const char* k : {"measured", "predicted"})
    if (const json* x = find(r, k)) {
      p.shown(k);
      p.section(std::string(k) + "-surface", std::string("The ") + k + " surface", kv_table(*x));
    }
  if (reg.is_object()) {
    p.shown("registration");
    p.section("registration", "Registration", kv_table(reg));
  }
  std::string d;
  const json& limit = get(r, {"pictures", "deviation_map_limit_um"});
  d += p.figure("images/deviation_map.png", "Deviation of the measured scan from the prediction, seen from above");
  if (limit.is_number() && p.has_picture("images/deviation_map.png")) d += colour_scale(limit);
  if (dev.is_object()) {
    p.shown("deviation");
    d += kv_table_um(dev, 3);
  }
  p.section("deviation", "Deviation map", d);
  if (marks.is_array()) {
    p.shown("marks");
    std::string s = marks.empty() ? "<p>No mark above the threshold.</p>\n" : marks_table(marks);
    s += kv_table(get(r, {"marks"}), {"list"});
    std::vector<std::pair<std::string, std::string>> prof;
    for (std::size_t k = 1; k <= marks.size() && k <= 3; ++k)
      prof.push_back({fmt::format("images/profile_mark_{}.png", k),
                      fmt::format("Mark {}: measured and predicted heights and their deviation across the path", k)});
    s += p.figures(prof);
    p.section("marks", "Marks and profiles", s);
  }
  if (const json* a = find(r, "areal")) {
    p.shown("areal");
    std::string s;
    if (const json* area = find(*a, "area")) s += "<p>Area: " + plain(*area) + ".</p>\n";
    s += side_by_side({{"measured", &get(*a, {"measured"})},
                       {"predicted", &get(*a, {"predicted"})},
                       {"measured − predicted", &get(*a, {"measured_minus_predicted"})}},
                      3);
    if (const json* proc = find(*a, "processing")) s += "<h3>Processing</h3>\n" + kv_table(*proc);
    p.section("areal", "Areal parameters (ISO 25178-2)", s);
  }
  if (const json* pics = find(r, "pictures")) {
    p.shown("pictures");
    if (const json* e = find(*pics, "error")) (void)e;  // said in the summary's note
  }
}

void oga_page(Page& p) {
  const json& r = p.report();
  const json& t = get(r, {"mse_table"});
  std::string summary = verdict_html(p);
  summary += kpi({
      {plain(get(t, {"c1_mse_um2"}), 4) + " → " + plain(get(t, {"c2_mse_um2"}), 4) + " µm²", "MSE(CE), C1 → C2"},
      {percent(get(t, {"change_percent"})), "change of MSE(CE)"},
      {um(get(t, {"c1_max_contour_error_um"})) + " → " + um(get(t, {"c2_max_contour_error_um"})),
       "contour error max, C1 → C2"},
      {plain(get(r, {"limits_held"})), "every axis limit held"},
      {seconds(get(r, {"interpolation", "cycle_time_s"})), "cycle time"},
      {seconds(get(r, {"timings_s", "total"})), "run time"},
  });
  if (const json* adv = find(r, "advice")) {
    p.shown("advice");
    if (!(adv->is_array() && adv->empty()) && !adv->is_null() && !(adv->is_string() && adv->get<std::string>().empty()))
      summary += "<div class=\"note\"><b>Advice:</b> " + value_html(*adv) + "</div>\n";
  }
  summary += pictures_note(p, true);
  p.section("summary", "Summary", summary);
  p.section("inputs", "Job and inputs", inputs_html(p));
  p.section("charts", "Before (C1) and after (C2)",
            p.figures({{"images/gains.png",
                        "Position-loop gains along the path, C1 and C2, with the curvature and the window starts"},
                       {"images/contour_error.png", "Contour error along the path with C1 and C2"},
                       {"images/contour_error_histogram.png", "Histogram of the contour error with C1 and C2"},
                       {"images/currents.png", "Current references with C1 and C2"}}));
  std::string gains;
  if (t.is_object()) {
    p.shown("mse_table");
    gains += "<h3>MSE table</h3>\n" + kv_table(t);
  }
  const json &c1 = get(r, {"c1"}), &c2 = get(r, {"c2"});
  if (c1.is_object() || c2.is_object()) {
    p.shown("c1");
    p.shown("c2");
    gains += "<h3>C1 (fixed gains) and C2 (gain schedule) per axis</h3>\n";
    for (const auto& [axis, x] : c1.items())
      if (x.is_object()) gains += "<h3>" + esc(axis) + "</h3>\n" + side_by_side({{"C1", &x}, {"C2", &get(c2, {axis})}});
    if (const json* src = find(c1, "source")) gains += "<p>C1: " + plain(*src) + ".</p>\n";
  }
  if (const json* b = find(r, "best_fixed_pair")) {
    p.shown("best_fixed_pair");
    gains += "<h3>Best admissible fixed pair</h3>\n" + (b->is_null() ? "<p>none admissible</p>\n" : kv_table(*b));
  }
  if (const json* a = find(r, "admissible")) {
    p.shown("admissible");
    gains += "<h3>Admissible configurations</h3>\n" + value_html(*a);
  }
  p.section("gains", "Gains and MSE", gains);
  if (const json* w = find(r, "windows")) {
    p.shown("windows");
    p.section("windows", "Windows", all_objects(*w) ? object_table(*w) : value_html(*w));
  }
  if (const json* v = find(r, "verification")) {
    p.shown("verification");
    std::string s;
    for (const auto& [axis, x] : v->items()) s += "<h3>Axis " + esc(axis) + "</h3>\n" + grouped(x);
    p.section("verification", "Verification against the limits", s);
  }
}

void plan_feed_page(Page& p) {
  const json& r = p.report();
  const json& runs = get(r, {"runs"});
  std::string summary = verdict_html(p);
  const json& plan = get(runs, {"plan"});
  summary += kpi({
      {seconds(get(runs, {"no_plan", "cycle_time_s"})) + " → " + seconds(get(plan, {"cycle_time_s"})),
       "cycle time, programmed feed → plan"},
      {um(get(runs, {"no_plan", "simulated_contour_error_max_um"})) + " → " +
           um(get(plan, {"simulated_contour_error_max_um"})),
       "contour error max (simulated), programmed feed → plan"},
      {um(get(r, {"limits", "contour_error_um"})), "contour error tolerance"},
      {plain(get(plan, {"within_tolerance"})), "plan within the tolerance"},
      {get(r, {"cycle_time_cost_of_contour_constraint"}).is_number()
           ? percent(json(r["cycle_time_cost_of_contour_constraint"].get<double>() * 100.0))
           : "",
       "cycle time cost of the contour constraint"},
      {seconds(get(r, {"timings_s", "total"})), "run time"},
  });
  summary += pictures_note(p, true);
  p.section("summary", "Summary", summary);
  p.section("inputs", "Job and inputs", inputs_html(p));
  p.section("charts", "Feed, axes and errors",
            p.figures({{"images/feed.png",
                        "Feed along the path: the bounds, the plan with and without the contour constraint"},
                       {"images/axes.png", "Axis velocity and acceleration with their limits"},
                       {"images/errors.png", "Chord and contour error with the tolerance"}}));
  if (runs.is_object()) {
    p.shown("runs");
    p.shown("cycle_time_cost_of_contour_constraint");
    std::string s = side_by_side({{"programmed feed", &get(runs, {"no_plan"})},
                                  {"plan without contour error", &get(runs, {"plan_without_contour_error"})},
                                  {"plan", &plan}});
    s += "<p>Cycle time cost of the contour constraint: " +
         (get(r, {"cycle_time_cost_of_contour_constraint"}).is_number()
              ? percent(json(r["cycle_time_cost_of_contour_constraint"].get<double>() * 100.0))
              : std::string("—")) +
         " (raw ratio " + plain(get(r, {"cycle_time_cost_of_contour_constraint"})) + ").</p>\n";
    p.section("runs", "Before and after: programmed feed, plans", s);
  }
  for (const auto& [k, title] : std::vector<std::pair<std::string, std::string>>{
           {"limits", "Limits"}, {"path", "Path"}, {"servo", "Servo model"}, {"lp", "Linear program"}})
    if (const json* x = find(r, k)) {
      p.shown(k);
      p.section("fig-" + k, title, kv_table(*x));
    }
}

void compensate_page(Page& p) {
  const json& r = p.report();
  const json& ce = get(r, {"contour_error"});
  const json& end = get(ce, {"compensated_program_on_machine"});
  const json& prog = get(r, {"compensated_program"});
  std::string summary = verdict_html(p);
  summary += kpi({
      {um_from_mm(get(end, {"before", "max_mm"})) + " → " + um_from_mm(get(end, {"after", "max_mm"})),
       "contour error max, original → compensated program on the machine"},
      {um_from_mm(get(end, {"before", "rms_mm"})) + " → " + um_from_mm(get(end, {"after", "rms_mm"})),
       "contour error RMS, original → compensated program on the machine"},
      {seconds(get(prog, {"cycle_time_original_s"})) + " → " + seconds(get(prog, {"cycle_time_compensated_program_s"})),
       "cycle time, original → compensated program"},
      {plain(get(r, {"limits", "compensated_within_limits"})), "compensated setpoints within the axis limits"},
      {seconds(get(r, {"timings_s", "total"})), "run time"},
  });
  summary += pictures_note(p, true);
  p.section("summary", "Summary", summary);
  p.section("inputs", "Job and inputs", inputs_html(p));
  p.section("charts", "Contour error before and after, along the path",
            p.figures({{"images/contour_error.png",
                        "Contour error before and after the compensation: as predicted, "
                        "and the compensated program on the machine's cascades"}}));
  if (ce.is_object()) {
    p.shown("contour_error");
    std::string s;
    for (const auto& [k, x] : ce.items()) {
      s += "<h3>" + words(k) + "</h3>\n";
      // Before, after and the change of each figure ("max_mm" before/after, "max" in change_percent).
      std::vector<std::vector<std::string>> rows;
      const json &before = get(x, {"before"}), &after = get(x, {"after"}), &change = get(x, {"change_percent"});
      for (const auto& [k, b] : before.items()) {
        std::string base = k;
        for (const char* unit : {"_mm", "_deg", "_rad"})
          if (ends_with(base, unit)) base = base.substr(0, base.size() - std::string_view(unit).size());
        rows.push_back({entry(k, b, 3).first, entry(k, b, 3).second, find(after, k) ? entry(k, after[k], 3).second : "",
                        find(change, base) ? percent(change[base]) : ""});
      }
      s += table({"", "before", "after", "change"}, rows, {false, true, true, true});
      s += kv_table(x, {"before", "after", "change_percent"});
    }
    p.section("before-after", "Contour error before and after", s);
  }
  if (prog.is_object()) {
    p.shown("compensated_program");
    p.section("program", "The compensated program", kv_table(prog));
  }
  if (const json* it = find(r, "iterations")) {
    p.shown("iterations");
    p.section("iterations", "Iterations", all_objects(*it) ? object_table(*it) : value_html(*it));
  }
  if (const json* l = find(r, "limits")) {
    p.shown("limits");
    p.section("limits", "Axis limits, original and compensated", grouped(*l));
  }
}

void study_page(Page& p) {
  const json& r = p.report();
  const json& vars = get(r, {"variations"});
  std::string summary = verdict_html(p);
  const json& sm = get(r, {"summary"});
  p.shown("summary");
  summary += kpi({{plain(get(sm, {"variations"})), "variations"},
                  {plain(get(sm, {"ok"})), "ok"},
                  {plain(get(sm, {"failed"})), "failed"},
                  {plain(get(sm, {"pending"})), "not finished"},
                  {plain(get(r, {"ranks"})), "MPI ranks"},
                  {seconds(get(r, {"timings_s", "total"})), "wall time"}});
  p.shown("ranks");
  p.section("summary", "Summary", summary);
  p.section("inputs", "Study and base job", inputs_html(p));
  if (!vars.is_array()) return;
  p.shown("variations");
  // The keys the variations set: those with the same value in every variation are said once, the others are the
  // table's first columns (as results.csv has them).
  std::vector<std::string> keys;
  std::map<std::string, std::set<std::string>> seen;
  std::map<std::string, std::size_t> count;
  for (const auto& v : vars)
    for (const auto& o : get(v, {"overrides"})) {
      const std::string k = str(at(o, "key"));
      if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
      seen[k].insert(str(at(o, "value")));
      ++count[k];
    }
  std::vector<std::string> varied, common;
  for (const auto& k : keys) (seen[k].size() == 1 && count[k] == vars.size() ? common : varied).push_back(k);
  std::string s =
      "<p>One row per variation, in the study's order: the deepest mark of each, and a link to its run's "
      "own page (its number).</p>\n";
  if (!common.empty()) {
    s += "<p>Every variation sets ";
    for (std::size_t i = 0; i < common.size(); ++i) {
      std::string where;
      for (const auto& o : get(vars.front(), {"overrides"}))
        if (str(at(o, "key")) == common[i]) where = str(at(o, "where"));
      s += (i ? ", " : "") + std::string("<code title=\"") + esc(where) + "\">" + esc(common[i]) + " = " +
           esc(*seen[common[i]].begin()) + "</code>";
    }
    s += ".</p>\n";
  }
  std::vector<std::string> head = {"#", "name"};
  for (const auto& k : varied) head.push_back("<code>" + esc(k) + "</code>");
  for (const char* h : {"status", "marks", "deepest mark", "kind", "deviation range", "contour error max",
                        "contour error RMS", "cycle time", "CPU time", "wall time", "rank"})
    head.push_back(h);
  std::vector<bool> numeric(head.size(), true);
  numeric[1] = numeric[2 + varied.size()] = numeric[5 + varied.size()] = false;
  std::vector<std::vector<std::string>> rows;
  for (const auto& v : vars) {
    const json& f = get(v, {"figures"});
    const std::string dir = str(at(v, "dir"));
    const std::string page = dir + "/report.html";
    std::error_code ec;
    const std::string index = plain(at(v, "variation"));
    std::vector<std::string> row = {!dir.empty() && fs::exists(p.dir() / page, ec)
                                        ? "<a href=\"" + url(page) + "\" title=\"" + esc(dir) + "\">" + index + "</a>"
                                        : "<span title=\"" + esc(dir) + "\">" + index + "</span>"};
    row.push_back(plain(at(v, "name")));
    for (const auto& k : varied) {
      std::string value;
      for (const auto& o : get(v, {"overrides"}))
        if (str(at(o, "key")) == k)  // the last one wins, as in the run; where the study sets it, on hover
          value = "<span title=\"" + esc(str(at(o, "where"))) + "\">" + esc(str(at(o, "value"))) + "</span>";
      row.push_back(value);
    }
    const std::string status = str(at(v, "status"));
    const std::string error = str(at(v, "error"));
    row.push_back(status == "ok" ? "ok" : "<b>" + esc(status) + "</b>" + (error.empty() ? "" : ": " + esc(error)));
    const bool ok = status == "ok";
    row.push_back(ok ? plain(at(f, "marks")) : "");
    row.push_back(um_from_mm(at(f, "mark_depth_mm")));
    row.push_back(plain(at(f, "mark_kind")));
    row.push_back(f.contains("deviation_min_mm")
                      ? um_from_mm(f["deviation_min_mm"]) + " … " + um_from_mm(at(f, "deviation_max_mm"))
                      : "—");
    row.push_back(um_from_mm(at(f, "contour_error_max_mm")));
    row.push_back(um_from_mm(at(f, "contour_error_rms_mm")));
    row.push_back(seconds(at(f, "cycle_time_s")));
    row.push_back(status == "pending" ? "" : seconds(at(v, "cpu_s")));
    row.push_back(status == "pending" ? "" : seconds(at(v, "wall_s")));
    row.push_back(status == "pending" ? "" : plain(at(v, "rank")));
    rows.push_back(row);
  }
  p.section("results", "Results", s + table(head, rows, numeric));
}

// Commands without their own sections (motion, measure, identify, ...): the summary, the inputs and every figure.
void generic_page(Page& p) {
  std::string summary = verdict_html(p);
  const json& ce = get(p.report(), {"contour_error", "cutting_moves"});
  summary += kpi({{ce.is_object() ? um_from_mm(get(ce, {"max_abs_mm"})) : "", "contour error max, cutting moves"},
                  {ce.is_object() ? um_from_mm(get(ce, {"rms_mm"})) : "", "contour error RMS, cutting moves"},
                  {seconds(get(p.report(), {"interpolation", "cycle_time_s"})), "cycle time"},
                  {seconds(get(p.report(), {"timings_s", "total"})), "run time"}});
  p.section("summary", "Summary", summary);
  p.section("inputs", "Job and inputs", p.report().contains("inputs") ? inputs_html(p) : "");
  if (str(at(p.report(), "command")) == "motion") motion_charts(p);
}

}  // namespace

std::string report_html(const nlohmann::json& report, const std::filesystem::path& dir) {
  Page p(report, dir);
  const std::string command = str(at(report, "command"));
  std::string name = str(at(report, "job"));
  if (command == "study") name = str(at(report, "study"));
  if (command == "compare")
    name = fs::path(str(get(report, {"inputs", "measured", "path"}))).filename().string() + " vs " +
           fs::path(str(get(report, {"inputs", "predicted", "path"}))).filename().string();
  p.shown("vmsim");
  p.shown("command");
  p.shown("job");
  if (command == "study") p.shown("study");

  if (command == "run")
    run_page(p);
  else if (command == "compare")
    compare_page(p);
  else if (command == "oga")
    oga_page(p);
  else if (command == "plan-feed")
    plan_feed_page(p);
  else if (command == "compensate")
    compensate_page(p);
  else if (command == "study")
    study_page(p);
  else
    generic_page(p);

  p.section("other-pictures", "Other pictures", p.other_figures());
  p.section("timings", "Timings", timings_html(p));
  const std::string files = files_html(p);  // before "All figures", which leaves out what is shown
  p.section("all", "All figures", rest_html(p));
  p.section("files", "Files", files);

  const std::string title =
      (command.empty() ? std::string("vmsim") : "vmsim " + command) + (name.empty() ? "" : ": " + name);
  const std::string what = command == "study" ? "study " : command == "compare" ? "" : "job ";
  const std::string subtitle = "vmsim " + esc(str(at(report, "vmsim"))) + " · <code>vmsim " + esc(command) + "</code>" +
                               (name.empty() ? "" : " · " + esc(what) + esc(name));
  return p.html(title, subtitle);
}

void write_report_html(const std::filesystem::path& dir, const nlohmann::json& report) {
  core::write_file_atomic(dir / "report.html", report_html(report, dir));
}

void write_report(const std::filesystem::path& file, const nlohmann::json& report) {
  core::write_file_atomic(file, report.dump(2) + "\n");
  if (file.filename() == "report.json") write_report_html(file.parent_path(), report);
}

}  // namespace vmsim::render
