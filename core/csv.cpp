#include "core/csv.hpp"
#include "core/regular_file.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

namespace vmsim::core {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

void split(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

// Cells quoted in messages are cut short: a hostile file's 1 MB cell does not make a 1 MB message.
std::string shown(std::string_view s) { return s.size() <= 40 ? std::string(s) : std::string(s.substr(0, 40)) + "..."; }

}  // namespace

std::optional<double> parse_number(std::string_view s) {
  if (s.empty()) return std::nullopt;
  std::size_t i = 0;
  if (s[0] == '+' || s[0] == '-') i = 1;
  // Digits or a point must follow the sign: from_chars would also take "inf" and "nan".
  if (i >= s.size() || !(std::isdigit(static_cast<unsigned char>(s[i])) || s[i] == '.')) return std::nullopt;
  // from_chars takes no '+'.
  const char* b = s.data() + (s[0] == '+' ? 1 : 0);
  const char* e = s.data() + s.size();
  double v = 0.0;
  const auto r = std::from_chars(b, e, v);
  if (r.ec != std::errc() || r.ptr != e || !std::isfinite(v)) return std::nullopt;
  return v;
}

bool is_nan_cell(std::string_view s) {
  if (!s.empty() && (s[0] == '+' || s[0] == '-')) s.remove_prefix(1);
  return s.size() == 3 && std::tolower(static_cast<unsigned char>(s[0])) == 'n' &&
         std::tolower(static_cast<unsigned char>(s[1])) == 'a' && std::tolower(static_cast<unsigned char>(s[2])) == 'n';
}

std::optional<std::pair<std::string_view, std::string_view>> comment_key_value(std::string_view line) {
  line = trim(line);
  if (line.empty() || line[0] != '#') return std::nullopt;
  line.remove_prefix(1);
  const std::size_t eq = line.find('=');
  if (eq == std::string_view::npos) return std::nullopt;
  const std::string_view key = trim(line.substr(0, eq));
  if (key.empty()) return std::nullopt;
  return std::make_pair(key, trim(line.substr(eq + 1)));
}

CsvReader::CsvReader(const std::filesystem::path& file, Header header)
    : owned_((require_regular_file(file), std::make_unique<std::ifstream>(file, std::ios::binary))),
      in_(owned_.get()),
      name_(file.string()) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) throw Error(located(name_, 0, "is a directory, not a CSV file"));
  if (!*owned_) throw Error(located(name_, 0, "cannot open the file"));
  start(header);
}

CsvReader::CsvReader(std::istream& in, std::string name, Header header) : in_(&in), name_(std::move(name)) {
  start(header);
}

void CsvReader::start(Header header) {
  if (header == Header::None || !read_line()) {
    return;
  }
  const bool named = header == Header::Required ||
                     (!cells_.empty() && !cells_[0].empty() && std::isalpha(static_cast<unsigned char>(cells_[0][0])));
  if (!named) {
    pending_ = true;
    return;
  }
  header_line_ = line_;
  for (std::size_t c = 0; c < cells_.size(); ++c) {
    for (std::size_t d = 0; d < c; ++d)
      if (cells_[d] == cells_[c])
        throw error(fmt::format("column '{}' appears twice (columns {} and {})", shown(cells_[c]), d + 1, c + 1));
    columns_.emplace_back(cells_[c]);
  }
  cells_.clear();
}

bool CsvReader::read_line() {
  while (std::getline(*in_, text_)) {
    ++read_;
    if (read_ == 1 && text_.compare(0, 3, "\xEF\xBB\xBF") == 0) text_.erase(0, 3);
    const std::string_view t = trim(text_);
    if (t.empty()) continue;
    if (t[0] == '#') {
      std::string_view whole = text_;
      if (!whole.empty() && whole.back() == '\r') whole.remove_suffix(1);
      comments_.push_back({read_, std::string(whole)});
      continue;
    }
    line_ = read_;
    split(t, cells_);
    return true;
  }
  if (in_->bad()) throw Error(located(name_, read_ + 1, "read error"));
  cells_.clear();
  return false;
}

bool CsvReader::next() {
  if (pending_) {
    pending_ = false;
  } else if (!read_line()) {
    return false;
  }
  if (has_header() && cells_.size() != columns_.size())
    throw error(
        fmt::format("{} cells, the header (line {}) names {} columns", cells_.size(), header_line_, columns_.size()));
  return true;
}

int CsvReader::column(std::string_view name) const {
  for (std::size_t c = 0; c < columns_.size(); ++c)
    if (columns_[c] == name) return static_cast<int>(c);
  return -1;
}

int CsvReader::require(std::string_view name) const {
  const int c = column(name);
  if (c < 0) {
    std::string found;
    for (const std::string& n : columns_) found += (found.empty() ? "" : ", ") + n;
    throw Error(located(name_, header_line_,
                        fmt::format("no column '{}' (found: {})", name, found.empty() ? "no header" : found)));
  }
  return c;
}

std::string CsvReader::column_label(std::size_t c) const {
  if (c < columns_.size()) return fmt::format("column {} '{}'", c + 1, shown(columns_[c]));
  return fmt::format("column {}", c + 1);
}

double CsvReader::number(std::size_t c) const {
  const std::string_view s = cell(c);
  if (const auto v = parse_number(s)) return *v;
  throw error(fmt::format("{}: '{}' is not a finite number", column_label(c), shown(s)));
}

double CsvReader::number_or_nan(std::size_t c, bool empty_is_nan) const {
  const std::string_view s = cell(c);
  if (is_nan_cell(s) || (empty_is_nan && s.empty())) return std::numeric_limits<double>::quiet_NaN();
  if (const auto v = parse_number(s)) return *v;
  throw error(fmt::format("{}: '{}' is not a finite number (nor nan{})", column_label(c), shown(s),
                          empty_is_nan ? ", nor empty" : ""));
}

Error CsvReader::error(const std::string& message, int line) const {
  return Error(located(name_, line > 0 ? line : line_, message));
}

void append_general(std::string& out, double v, int precision) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, precision);
  out.append(buf, r.ptr);
}

void append_shortest(std::string& out, double v) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::scientific);
  const char* e = std::find(buf, r.ptr, 'e');
  if (e == r.ptr) {  // inf, nan
    out.append(buf, r.ptr);
    return;
  }
  int exp = 0;
  std::from_chars(e + 1 + (e[1] == '+'), r.ptr, exp);
  // fmt's rule for its shortest form: fixed notation for decimal exponents -4 .. 15, the exponent form otherwise.
  if (exp < -4 || exp >= 16) {
    out.append(buf, r.ptr);
    return;
  }
  const char* d = buf;
  if (*d == '-') out += '-', ++d;
  char digits[20];  // the significant digits without the point (at most 17)
  int n = 0;
  for (; d < e; ++d)
    if (*d != '.') digits[n++] = *d;
  if (exp < 0) {
    out.append("0.");
    out.append(static_cast<std::size_t>(-exp - 1), '0');
    out.append(digits, static_cast<std::size_t>(n));
  } else if (n <= exp + 1) {
    out.append(digits, static_cast<std::size_t>(n));
    out.append(static_cast<std::size_t>(exp + 1 - n), '0');
  } else {
    out.append(digits, static_cast<std::size_t>(exp + 1));
    out += '.';
    out.append(digits + exp + 1, static_cast<std::size_t>(n - exp - 1));
  }
}

void CsvWriter::comment(std::string_view text) {
  auto& s = out_.stream();
  s << "# " << text << '\n';
}

void CsvWriter::header(const std::vector<std::string>& names) {
  auto& s = out_.stream();
  for (std::size_t c = 0; c < names.size(); ++c) s << (c ? "," : "") << names[c];
  s << '\n';
}

void CsvWriter::row(std::string_view cells) {
  auto& s = out_.stream();
  s << cells << '\n';
}

}  // namespace vmsim::core
