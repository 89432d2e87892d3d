// core/csv: what the reader accepts (comments, blank lines, CR LF, a byte-order mark, blanks around cells, a header
// map), how strictly it reads numbers (std::from_chars over the whole cell, finite), and that every error names the
// file, the line and the column with what was expected; the writer's bytes read back to the same values.
#include "core/csv.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace {

using vmsim::core::CsvReader;

std::string error_of(const std::string& text, CsvReader::Header h = CsvReader::Header::Required) {
  try {
    std::istringstream in(text);
    CsvReader r(in, "t.csv", h);
    while (r.next())
      for (std::size_t c = 0; c < r.cells(); ++c) (void)r.number(c);
  } catch (const vmsim::core::Error& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Csv, CommentsBlankLinesAndHeaderMap) {
  std::istringstream in(
      "\xEF\xBB\xBF# vmsim thing 1: a title\r\n# period_s = 0.001\r\n\r\n t_s , X_mm,Y_mm\r\n"
      "0,1.5,-2\r\n# a comment between rows\n   \n0.001, +3 ,4e-3\n");
  CsvReader r(in, "t.csv");
  ASSERT_TRUE(r.has_header());
  EXPECT_EQ(r.header_line(), 4);
  EXPECT_EQ(r.columns(), (std::vector<std::string>{"t_s", "X_mm", "Y_mm"}));
  EXPECT_EQ(r.column("X_mm"), 1);
  EXPECT_EQ(r.column("Z_mm"), -1);
  EXPECT_EQ(r.require("Y_mm"), 2);
  ASSERT_EQ(r.comments().size(), 2u);
  EXPECT_EQ(r.comments()[0].line, 1);
  EXPECT_EQ(r.comments()[0].text, "# vmsim thing 1: a title");  // the byte-order mark and the CR gone
  const auto kv = vmsim::core::comment_key_value(r.comments()[1].text);
  ASSERT_TRUE(kv);
  EXPECT_EQ(kv->first, "period_s");
  EXPECT_EQ(kv->second, "0.001");
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.line(), 5);
  EXPECT_EQ(r.number(1), 1.5);
  EXPECT_EQ(r.number(2), -2.0);
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.line(), 8);
  EXPECT_EQ(r.cell(1), "+3");
  EXPECT_EQ(r.number(1), 3.0);
  EXPECT_EQ(r.number(2), 4e-3);
  EXPECT_EQ(r.comments().size(), 3u);  // the one between the rows, as it was passed
  EXPECT_FALSE(r.next());
  EXPECT_FALSE(r.next());
}

TEST(Csv, NumbersAreReadStrictlyAndExactly) {
  using vmsim::core::parse_number;
  EXPECT_EQ(parse_number("0.1"), 0.1);  // correctly rounded, as strtod
  EXPECT_EQ(parse_number("-1e-300"), -1e-300);
  EXPECT_EQ(parse_number(".5"), 0.5);
  EXPECT_EQ(parse_number("+2"), 2.0);
  EXPECT_EQ(parse_number("2."), 2.0);
  EXPECT_EQ(parse_number("1.7976931348623157e308"), 1.7976931348623157e308);
  for (const char* bad : {"", " ", "1.5x", "1,5", "0x10", "inf", "-inf", "nan", "NaN", "infinity", "1e999", "--1",
                          "+-1", "e5", ".", "+", "1 2", "１"})
    EXPECT_FALSE(parse_number(bad)) << bad;
  EXPECT_TRUE(vmsim::core::is_nan_cell("nan"));
  EXPECT_TRUE(vmsim::core::is_nan_cell("-NaN"));
  EXPECT_FALSE(vmsim::core::is_nan_cell("nano"));
  // Shortest round-trip text reads back bit for bit.
  for (const double v : {0.1, 1.0 / 3, -2.5e-17, 123456.789e10, 5e-324})
    EXPECT_EQ(parse_number(fmt::format("{}", v)), v);
}

TEST(Csv, ErrorsNameFileLineColumnAndWhatWasExpected) {
  EXPECT_EQ(error_of("a,b\n1,2\n1,x\n"), "t.csv:3: column 2 'b': 'x' is not a finite number");
  EXPECT_EQ(error_of("a,b\n1,2\n1,2,3\n"), "t.csv:3: 3 cells, the header (line 1) names 2 columns");
  EXPECT_EQ(error_of("a,b\n1\n"), "t.csv:2: 1 cells, the header (line 1) names 2 columns");
  EXPECT_EQ(error_of("# c\na,b,a\n"), "t.csv:2: column 'a' appears twice (columns 1 and 3)");
  EXPECT_EQ(error_of("a,b\n1,inf\n"), "t.csv:2: column 2 'b': 'inf' is not a finite number");
  EXPECT_EQ(error_of("a,b\n1,\n"), "t.csv:2: column 2 'b': '' is not a finite number");
  EXPECT_EQ(error_of("1,2\n3,4x\n", CsvReader::Header::None), "t.csv:2: column 2: '4x' is not a finite number");
  // A long cell is cut short in the message.
  const std::string err = error_of("a\n" + std::string(100000, '7') + "q\n");
  EXPECT_LT(err.size(), 120u) << err;
  std::istringstream in("x,y\n1,2\n");
  CsvReader r(in, "t.csv");
  try {
    r.require("z");
    FAIL();
  } catch (const vmsim::core::Error& e) {
    EXPECT_EQ(std::string(e.what()), "t.csv:1: no column 'z' (found: x, y)");
  }
  // NaN where a file allows it.
  ASSERT_TRUE(r.next());
  std::istringstream in2("g\nnan\n\n");
  CsvReader r2(in2, "g.csv");
  ASSERT_TRUE(r2.next());
  EXPECT_TRUE(std::isnan(r2.number_or_nan(0)));
  EXPECT_THROW(r2.number(0), vmsim::core::Error);
}

TEST(Csv, OptionalHeaderAndFiles) {
  std::istringstream named("x,y\n1,2\n"), bare("# c\n1,2\n3,4\n");
  CsvReader a(named, "a.csv", CsvReader::Header::Optional), b(bare, "b.csv", CsvReader::Header::Optional);
  EXPECT_TRUE(a.has_header());
  EXPECT_FALSE(b.has_header());
  ASSERT_TRUE(b.next());
  EXPECT_EQ(b.line(), 2);
  EXPECT_EQ(b.number(1), 2.0);
  ASSERT_TRUE(b.next());
  EXPECT_FALSE(b.next());
  // Empty and comment-only files: no header, no rows.
  std::istringstream empty("# only\n\n");
  CsvReader c(empty, "c.csv");
  EXPECT_FALSE(c.has_header());
  EXPECT_FALSE(c.next());
  // Files: a missing one and a directory are errors naming the path.
  EXPECT_THROW(CsvReader("/nonexistent/vmsim.csv"), vmsim::core::Error);
  try {
    CsvReader d(std::filesystem::temp_directory_path());
    FAIL();
  } catch (const vmsim::core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos);
  }
}

TEST(Csv, WriterReadsBack) {
  const auto p = std::filesystem::temp_directory_path() / ("vmsim_csv_test_" + std::to_string(::getpid()) + ".csv");
  {
    vmsim::core::CsvWriter w(p);
    w.comment("vmsim test 1");
    w.comment("k=v");
    w.header({"a", "b"});
    w.row("0.1,nan");
    w.row("-3,2.5e-10");
    w.commit();
  }
  std::ifstream f(p, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "# vmsim test 1\n# k=v\na,b\n0.1,nan\n-3,2.5e-10\n");
  CsvReader r(p);
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.number(0), 0.1);
  EXPECT_TRUE(std::isnan(r.number_or_nan(1)));
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.number(1), 2.5e-10);
  std::filesystem::remove(p);
}
