// Position traces (sysid/position_trace, through core/csv): what write_position_trace_csv writes reads back to the
// same samples within its printed digits (t 7 decimals, positions 10), degrees become rad; columns in any order, '#'
// lines, a byte-order mark and CR LF are accepted; each malformed file is refused with its file, line and what was
// expected.
#include "sysid/position_trace.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

namespace vmsim::sysid {
namespace {

std::filesystem::path temp(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("vmsim_trace_" + std::to_string(::getpid()) + "_" + name);
}

std::string error_of(const std::string& text) {
  const auto p = temp("bad.csv");
  std::ofstream(p, std::ios::binary) << text;
  std::string what = "no error";
  try {
    (void)read_position_trace_csv(p);
  } catch (const core::Error& e) {
    what = e.what();
    what = what.substr(what.find("bad.csv"));
  }
  std::filesystem::remove(p);
  return what;
}

}  // namespace

TEST(PositionTrace, WrittenTraceReadsBack) {
  PositionTrace tr;
  const Eigen::Index n = 500;
  tr.period_s = 1e-3;
  tr.t_s = Eigen::ArrayXd::LinSpaced(n, 0, (n - 1) * 1e-3);
  tr.axes = {"X", "C"};
  tr.rotary = {false, true};
  tr.command.resize(n, 2);
  tr.actual.resize(n, 2);
  for (Eigen::Index k = 0; k < n; ++k) {
    tr.command(k, 0) = 10 * std::sin(0.01 * k);
    tr.actual(k, 0) = tr.command(k, 0) - 1e-3 * std::cos(0.01 * k);
    tr.command(k, 1) = 0.5 * std::sin(0.02 * k);  // rad
    tr.actual(k, 1) = 0.999 * tr.command(k, 1);
  }
  const auto p = temp("ok.csv");
  write_position_trace_csv(p, tr, {"a trace for the test"});
  const PositionTrace r = read_position_trace_csv(p);
  std::filesystem::remove(p);
  ASSERT_EQ(r.t_s.size(), n);
  EXPECT_EQ(r.axes, tr.axes);
  EXPECT_EQ(r.rotary, tr.rotary);
  EXPECT_NEAR(r.period_s, 1e-3, 1e-12);
  EXPECT_LE((r.t_s - tr.t_s).abs().maxCoeff(), 0.5e-7);
  EXPECT_LE((r.command.col(0) - tr.command.col(0)).cwiseAbs().maxCoeff(), 0.5e-10);
  EXPECT_LE((r.actual.col(0) - tr.actual.col(0)).cwiseAbs().maxCoeff(), 0.5e-10);
  // C in the file in degrees, 10 decimals: back in rad within 0.5e-10 deg.
  EXPECT_LE((r.command.col(1) - tr.command.col(1)).cwiseAbs().maxCoeff(), 0.5e-10 * std::numbers::pi / 180 * 1.001);
  EXPECT_EQ(r.axis_index("C"), 1);
  EXPECT_EQ(r.axis_index("Y"), -1);
}

TEST(PositionTrace, ColumnsInAnyOrderWithCommentsBomAndCrLf) {
  const auto p = temp("order.csv");
  std::ofstream(p, std::ios::binary) << "\xEF\xBB\xBF# from a controller\r\nZ_actual_mm, t_s ,Z_command_mm\r\n"
                                        "1.0,0.000,1.5\r\n# pause\r\n2.0,0.002,2.5\r\n3.0,0.004,3.5\r\n";
  const PositionTrace r = read_position_trace_csv(p);
  std::filesystem::remove(p);
  ASSERT_EQ(r.t_s.size(), 3);
  EXPECT_EQ(r.axes, std::vector<std::string>{"Z"});
  EXPECT_EQ(r.command(2, 0), 3.5);
  EXPECT_EQ(r.actual(1, 0), 2.0);
  EXPECT_DOUBLE_EQ(r.period_s, 0.002);
}

TEST(PositionTrace, MalformedFilesNameTheLine) {
  const std::string head = "t_s,X_command_mm,X_actual_mm\n";
  EXPECT_EQ(error_of(""), "bad.csv: no header row (expected t_s, <AXIS>_command_mm, <AXIS>_actual_mm, ...)");
  EXPECT_EQ(error_of("t_s,X_command_mm,X_position_mm\n"),
            "bad.csv:1: column 3 'X_position_mm': unknown column (expected t_s or <AXIS>_command_<unit>, "
            "<AXIS>_actual_<unit> with AXIS in X Y Z A B C)");
  EXPECT_EQ(error_of("t_s,A_command_mm,A_actual_mm\n"), "bad.csv:1: column 2 'A_command_mm': axis A is given in deg");
  EXPECT_EQ(error_of("t_s,X_command_mm\n0,1\n0.001,1\n"), "bad.csv:1: axis X needs both X_command_mm and X_actual_mm");
  EXPECT_EQ(error_of("X_command_mm,X_actual_mm\n"), "bad.csv:1: no t_s column");
  EXPECT_EQ(error_of(head + "0,1,1\n0.001,1,x\n"), "bad.csv:3: column 3 'X_actual_mm': 'x' is not a finite number");
  EXPECT_EQ(error_of(head + "0,1,1\n0.001,1\n"), "bad.csv:3: 2 cells, the header (line 1) names 3 columns");
  EXPECT_EQ(error_of(head + "0,1,1\n"), "bad.csv: 1 samples; a trace needs at least 2");
  // Uneven steps are resampled (sysid/trace_formats_test); steps that do not advance are errors.
  EXPECT_EQ(error_of(head + "0,1,1\n0.001,1,1\n0.001,1,1\n"),
            "bad.csv:4: t_s 0.001 s does not increase (previous sample: 0.001 s)");
  EXPECT_EQ(error_of("t_s,X_command_mm,X_actual_mm,t_s\n"), "bad.csv:1: column 't_s' appears twice (columns 1 and 4)");
}

}  // namespace vmsim::sysid
