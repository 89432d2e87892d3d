// contour_error's input check (issue 21: now one contiguous finiteness pass first): a value that is not finite is still
// named by its matrix, row and column, for NaN and both infinities, in the command and in the actual path, and finite
// inputs pass. Reference: the positions planted by the test.
#include "core/error.hpp"
#include "motion/contour.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace vmsim::motion {
namespace {

Eigen::MatrixXd contour_inputs_line(Eigen::Index n) {
  Eigen::MatrixXd m(n, 3);
  for (Eigen::Index k = 0; k < n; ++k) m.row(k) << 0.1 * k, 0.02 * k * k, 1.0;
  return m;
}

std::string contour_inputs_error(const Eigen::MatrixXd& c, const Eigen::MatrixXd& a) {
  try {
    (void)contour_error(c, a);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

TEST(ContourInputs, ANonFiniteValueIsNamedByMatrixRowAndColumn) {
  const double bad[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                        -std::numeric_limits<double>::infinity()};
  for (const double v : bad) {
    for (int which = 0; which < 2; ++which) {
      for (const auto& [row, col] : {std::pair{0, 0}, std::pair{17, 2}, std::pair{199, 1}}) {
        Eigen::MatrixXd c = contour_inputs_line(200), a = contour_inputs_line(200);
        (which == 0 ? c : a)(row, col) = v;
        // A second bad value later: the first is named.
        (which == 0 ? c : a)(199, 2) = v;
        const std::string e = contour_inputs_error(c, a);
        const std::string want = std::string("contour_error: the ") + (which == 0 ? "command" : "actual") + " row " +
                                 std::to_string(row) + " column " + std::to_string(row == 199 ? 1 : col) +
                                 " is not finite";
        EXPECT_EQ(e, want) << v << " " << which << " " << row;
      }
    }
  }
  // Both bad: the command is named first.
  Eigen::MatrixXd c = contour_inputs_line(50), a = contour_inputs_line(50);
  c(30, 1) = bad[0];
  a(3, 0) = bad[1];
  EXPECT_EQ(contour_inputs_error(c, a), "contour_error: the command row 30 column 1 is not finite");
  // Finite inputs pass.
  const Eigen::MatrixXd ok = contour_inputs_line(50);
  EXPECT_EQ(contour_inputs_error(ok, ok), "");
}

}  // namespace
}  // namespace vmsim::motion
