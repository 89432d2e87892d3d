#include "core/toml_reader.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace vmsim::core {

namespace {
std::string type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table:
      return "a table";
    case toml::node_type::array:
      return "an array";
    case toml::node_type::string:
      return "a string";
    case toml::node_type::integer:
      return "an integer";
    case toml::node_type::floating_point:
      return "a number";
    case toml::node_type::boolean:
      return "a boolean";
    default:
      return "a date/time";
  }
}
}  // namespace

TomlTable::TomlTable(const toml::table& table, std::string file, std::string key_prefix)
    : table_(&table), file_(std::move(file)), prefix_(std::move(key_prefix)) {}

std::string TomlTable::full_key(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }

std::string TomlTable::where(const toml::node* node) const {
  const auto& src = (node ? node->source() : table_->source());
  if (src.begin.line > 0) return fmt::format("{}:{}:{}", file_, src.begin.line, src.begin.column);
  return file_;
}

void TomlTable::fail(const std::string& key, const std::string& message) const {
  const toml::node* node = table_->get(key);
  throw Error(fmt::format("{}: key '{}': {}", where(node), full_key(key), message));
}

const toml::node* TomlTable::get(const std::string& key) const {
  used_.insert(key);
  return table_->get(key);
}

bool TomlTable::has(const std::string& key) const { return table_->contains(key); }

std::optional<double> TomlTable::opt_number(const std::string& key) const {
  const toml::node* n = get(key);
  if (!n) return std::nullopt;
  if (auto v = n->value<double>(); v && (n->is_floating_point() || n->is_integer())) {
    if (!std::isfinite(*v)) fail(key, "expected a finite number");
    return *v;
  }
  fail(key, "expected a number, found " + type_name(*n));
}

double TomlTable::number(const std::string& key) const {
  if (auto v = opt_number(key)) return *v;
  fail(key, "missing (expected a number)");
}

std::optional<double> TomlTable::opt_positive(const std::string& key) const {
  auto v = opt_number(key);
  if (v && !(*v > 0)) fail(key, fmt::format("expected a number > 0, found {}", *v));
  return v;
}

double TomlTable::positive(const std::string& key) const {
  if (auto v = opt_positive(key)) return *v;
  fail(key, "missing (expected a number > 0)");
}

std::optional<double> TomlTable::opt_nonnegative(const std::string& key) const {
  auto v = opt_number(key);
  if (v && !(*v >= 0)) fail(key, fmt::format("expected a number >= 0, found {}", *v));
  return v;
}

std::optional<long long> TomlTable::opt_integer(const std::string& key) const {
  const toml::node* n = get(key);
  if (!n) return std::nullopt;
  if (!n->is_integer()) fail(key, "expected an integer, found " + type_name(*n));
  return n->value<long long>();
}

long long TomlTable::integer(const std::string& key) const {
  if (auto v = opt_integer(key)) return *v;
  fail(key, "missing (expected an integer)");
}

std::optional<std::string> TomlTable::opt_string(const std::string& key) const {
  const toml::node* n = get(key);
  if (!n) return std::nullopt;
  if (!n->is_string()) fail(key, "expected a string, found " + type_name(*n));
  return *n->value<std::string>();
}

std::string TomlTable::string(const std::string& key) const {
  if (auto v = opt_string(key)) return *v;
  fail(key, "missing (expected a string)");
}

std::optional<std::string> TomlTable::opt_choice(const std::string& key,
                                                 const std::vector<std::string>& allowed) const {
  auto v = opt_string(key);
  if (!v) return v;
  for (const auto& a : allowed)
    if (*v == a) return v;
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "\"" : ", \"") + a + "\"";
  fail(key, fmt::format("\"{}\" is not one of {}", *v, list));
}

std::string TomlTable::choice(const std::string& key, const std::vector<std::string>& allowed) const {
  if (auto v = opt_choice(key, allowed)) return *v;
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "\"" : ", \"") + a + "\"";
  fail(key, "missing (expected one of " + list + ")");
}

std::optional<bool> TomlTable::opt_boolean(const std::string& key) const {
  const toml::node* n = get(key);
  if (!n) return std::nullopt;
  if (!n->is_boolean()) fail(key, "expected true or false, found " + type_name(*n));
  return *n->value<bool>();
}

std::optional<std::vector<double>> TomlTable::opt_numbers(const std::string& key, std::size_t n) const {
  const toml::node* node = get(key);
  if (!node) return std::nullopt;
  const toml::array* arr = node->as_array();
  if (!arr) fail(key, "expected an array of numbers, found " + type_name(*node));
  std::vector<double> out;
  for (const auto& el : *arr) {
    auto v = el.value<double>();
    if (!v || !(el.is_floating_point() || el.is_integer()))
      fail(key, "expected an array of finite numbers, found an element that is " + type_name(el));
    if (!std::isfinite(*v)) fail(key, "expected an array of finite numbers, found nan or inf");
    out.push_back(*v);
  }
  if (n > 0 && out.size() != n) fail(key, fmt::format("expected {} numbers, found {}", n, out.size()));
  return out;
}

std::vector<double> TomlTable::numbers(const std::string& key, std::size_t n) const {
  if (auto v = opt_numbers(key, n)) return *v;
  fail(key, n > 0 ? fmt::format("missing (expected an array of {} numbers)", n) : "missing (expected an array)");
}

std::optional<std::filesystem::path> TomlTable::opt_existing_path(const std::string& key) const {
  auto s = opt_string(key);
  if (!s) return std::nullopt;
  std::filesystem::path p(*s);
  if (p.is_relative()) p = std::filesystem::path(file_).parent_path() / p;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec))
    fail(key, fmt::format("file \"{}\" does not exist (relative paths are taken from the directory of {})", p.string(),
                          file_));
  return p;
}

std::filesystem::path TomlTable::existing_path(const std::string& key) const {
  if (auto v = opt_existing_path(key)) return *v;
  fail(key, "missing (expected a file path)");
}

std::optional<TomlTable> TomlTable::opt_table(const std::string& key) const {
  const toml::node* n = get(key);
  if (!n) return std::nullopt;
  const toml::table* t = n->as_table();
  if (!t) fail(key, "expected a table, found " + type_name(*n));
  return TomlTable(*t, file_, full_key(key));
}

TomlTable TomlTable::table(const std::string& key) const {
  if (auto t = opt_table(key)) return *t;
  fail(key, "missing table [" + full_key(key) + "]");
}

std::vector<TomlTable> TomlTable::array_of_tables(const std::string& key) const {
  const toml::node* n = get(key);
  std::vector<TomlTable> out;
  if (!n) return out;
  const toml::array* arr = n->as_array();
  if (!arr) fail(key, "expected an array of tables ([[" + full_key(key) + "]]), found " + type_name(*n));
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const toml::table* t = (*arr)[i].as_table();
    if (!t) fail(key, fmt::format("element {} is {}, expected a table", i, type_name((*arr)[i])));
    out.emplace_back(*t, file_, fmt::format("{}[{}]", full_key(key), i));
  }
  return out;
}

void TomlTable::finish() const {
  for (const auto& [k, v] : *table_) {
    const std::string key(k.str());
    if (!used_.count(key)) {
      throw Error(fmt::format("{}: unknown key '{}' (misspelt, or not valid here; see parts/README.md)", where(&v),
                              full_key(key)));
    }
  }
}

toml::table parse_toml_file(const std::filesystem::path& path) {
  // A directory opens as an empty stream and would read as an empty file ("missing table ...").
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw Error(fmt::format("{}: cannot open file (it does not exist or is not a regular file)", path.string()));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(fmt::format("{}: cannot open file", path.string()));
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    return toml::parse(ss.str(), path.string());
  } catch (const toml::parse_error& e) {
    const auto& src = e.source();
    throw Error(fmt::format("{}:{}:{}: TOML syntax error: {}", path.string(), src.begin.line, src.begin.column,
                            e.description()));
  }
}

}  // namespace vmsim::core
