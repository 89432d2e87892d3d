#pragma once
// Strict TOML reading for machine and job files: every key a reader asks for is checked for type and
// range, and any key nobody asked for is an error (a typo must never be ignored silently). Every error
// names the file, the line and column, the full key, and what was expected.
#include <toml++/toml.h>

#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace vmsim::core {

class TomlTable {
 public:
  TomlTable(const toml::table& table, std::string file, std::string key_prefix);

  // Required values (error when absent) and optional ones (nullopt when absent). Numbers accept integers.
  double number(const std::string& key) const;
  std::optional<double> opt_number(const std::string& key) const;
  double positive(const std::string& key) const;  // > 0
  std::optional<double> opt_positive(const std::string& key) const;
  std::optional<double> opt_nonnegative(const std::string& key) const;
  long long integer(const std::string& key) const;
  std::optional<long long> opt_integer(const std::string& key) const;
  std::string string(const std::string& key) const;
  std::optional<std::string> opt_string(const std::string& key) const;
  // One of the listed strings.
  std::string choice(const std::string& key, const std::vector<std::string>& allowed) const;
  std::optional<std::string> opt_choice(const std::string& key, const std::vector<std::string>& allowed) const;
  std::optional<bool> opt_boolean(const std::string& key) const;
  // An array of numbers; when n > 0 it must have exactly n entries.
  std::vector<double> numbers(const std::string& key, std::size_t n = 0) const;
  std::optional<std::vector<double>> opt_numbers(const std::string& key, std::size_t n = 0) const;
  // A file path, resolved against the directory of the TOML file; must exist.
  std::filesystem::path existing_path(const std::string& key) const;
  std::optional<std::filesystem::path> opt_existing_path(const std::string& key) const;

  bool has(const std::string& key) const;
  TomlTable table(const std::string& key) const;
  std::optional<TomlTable> opt_table(const std::string& key) const;
  std::vector<TomlTable> array_of_tables(const std::string& key) const;

  // Throws naming every key of this table that no accessor asked for.
  void finish() const;

  // "file:line:col: key 'prefix.key': message"
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;
  const std::string& file() const { return file_; }
  std::string full_key(const std::string& key) const;

 private:
  const toml::node* get(const std::string& key) const;
  std::string where(const toml::node* node) const;

  const toml::table* table_;
  std::string file_;
  std::string prefix_;
  mutable std::set<std::string> used_;
};

// Parses a TOML file; syntax errors name the file, line and column.
toml::table parse_toml_file(const std::filesystem::path& path);

}  // namespace vmsim::core
