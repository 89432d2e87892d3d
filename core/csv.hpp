#pragma once
// vmsim's CSV files (position and axis traces, signals, gain schedules, needles, height grids, NURBS curves), read
// and written in one place. The dialect is the one those files use: UTF-8 (a byte-order mark is skipped), cells
// separated by commas and trimmed of blanks, no quoting (none of these files has a comma inside a cell),
// '#' lines (comments, or "# key=value" metadata) and blank lines anywhere, an optional header row naming the
// columns, CR LF or LF line ends. Numbers are read strictly: the whole cell is a decimal number (std::from_chars:
// optional sign, digits, optional fraction and exponent), finite. Every error names the file and line, and the
// column where there is one, and says what was expected.
#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <filesystem>
#include <fstream>
#include <istream>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace vmsim::core {

// The whole cell as a finite decimal number, or nothing (empty, words, trailing characters, inf, nan, overflow).
std::optional<double> parse_number(std::string_view cell);
// "nan" in any case, with an optional sign: the token vmsim writes for an undefined value.
bool is_nan_cell(std::string_view cell);
// A comment line "# key=value" (or "#key=value") as (key, value), both trimmed; nothing without '=' or with an empty
// key.
std::optional<std::pair<std::string_view, std::string_view>> comment_key_value(std::string_view comment_line);

struct CsvComment {
  int line = 0;
  std::string text;  // the whole line, '#' included (line end removed)
};

// Reads a CSV file row by row (traces of millions of rows are never held as text):
//   CsvReader r(path);                 // the '#' lines and the header before the first row are read
//   const int t = r.require("t_s");    // column by name
//   while (r.next()) { double v = r.number(t); ... }
class CsvReader {
 public:
  enum class Header {
    Required,  // the first line that is not a comment nor blank names the columns
    None,      // every line is a row (a matrix)
    Optional,  // a header when the first such line's first cell starts with a letter
  };
  // Throws core::Error when the file cannot be opened.
  explicit CsvReader(const std::filesystem::path& file, Header header = Header::Required);
  // `in` must outlive the reader; `name` starts every error message.
  CsvReader(std::istream& in, std::string name, Header header = Header::Required);
  CsvReader(const CsvReader&) = delete;
  CsvReader& operator=(const CsvReader&) = delete;

  const std::string& name() const { return name_; }
  // The header's column names (empty without a header: the file had no line but comments, or Header::None).
  const std::vector<std::string>& columns() const { return columns_; }
  bool has_header() const { return !columns_.empty(); }
  int header_line() const { return header_line_; }
  // The column's index, or -1.
  int column(std::string_view name) const;
  // The column's index; throws "file:header line: no column 'name' (found: a, b, c)".
  int require(std::string_view name) const;
  // The comment lines read so far (those before the header or first row once constructed; more as rows are read).
  const std::vector<CsvComment>& comments() const { return comments_; }

  // Moves to the next row; false at the end of the file. With a header, a row of another width is an error.
  bool next();
  int line() const { return line_; }  // 1-based line of the current row
  std::size_t cells() const { return cells_.size(); }
  std::string_view cell(std::size_t c) const { return cells_.at(c); }
  // The cell as a finite number; throws "file:line: column N 'name': 'text' is not a finite number".
  double number(std::size_t c) const;
  // The same, but "nan" (or, with empty_is_nan, an empty cell) gives NaN.
  double number_or_nan(std::size_t c, bool empty_is_nan = false) const;
  // "file:line: message" for the current row (line > 0: that line instead).
  Error error(const std::string& message, int line = 0) const;
  // How column c is named in messages: "column 3 'x_mm'", or "column 3" without a header.
  std::string column_label(std::size_t c) const;

 private:
  void start(Header header);
  bool read_line();  // the next non-comment, non-blank line into cells_; false at the end

  std::unique_ptr<std::ifstream> owned_;
  std::istream* in_ = nullptr;
  std::string name_;
  std::vector<std::string> columns_;
  int header_line_ = 0;
  std::vector<CsvComment> comments_;
  std::string text_;                     // the current line
  std::vector<std::string_view> cells_;  // into text_
  int line_ = 0, read_ = 0;
  bool pending_ = false;  // the first row was read while looking for a header
};

// A number appended to a row being built, through std::to_chars into the row's own buffer (issue 21: fmt::format per
// number, a temporary string each, was most of the time spent writing signals): the bytes of fmt's "{:.pg}" (printf's
// %.pg: p significant digits, trailing zeros dropped, two-digit exponents). Values that are not finite come out as
// to_chars writes them (inf, -inf, nan, -nan): files that write a token of their own test first.
void append_general(std::string& out, double v, int precision);

// A number appended with the shortest digits that read back as the same double, through std::to_chars into the row's
// buffer: the bytes of fmt's "{}" (exponent form below 1e-4 and from 1e16 on, two-digit exponents; "1" for 1.0, "-0"
// for -0.0), which the height grids were written with before (issue 21: a string per number, half the grid's write).
// Values that are not finite come out as to_chars writes them: files that write a token of their own test first.
void append_shortest(std::string& out, double v);

// Writes a CSV file atomically (core/atomic_file): '#' comment lines, a header row, then rows the caller formats
// (each file has its own number formats, chosen so that reading back gives the same values).
class CsvWriter {
 public:
  explicit CsvWriter(const std::filesystem::path& file) : out_(file) {}
  // "# text"
  void comment(std::string_view text);
  // The names joined by commas.
  void header(const std::vector<std::string>& names);
  // One row, its cells already joined by commas (no line end).
  void row(std::string_view cells);
  std::ostream& stream() { return out_.stream(); }
  // Flushes, checks and renames into place; throws core::Error on I/O errors.
  void commit() { out_.commit(); }

 private:
  AtomicFile out_;
};

}  // namespace vmsim::core
