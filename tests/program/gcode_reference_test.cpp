// The G-code reader against LinuxCNC's own interpreter: the canonical calls `rs274 -g` printed for real
// programs (../shared/data/gcode/rs274_canon, written outside the project), and the cutter-compensation
// program vmsim must refuse.
#include "gcode_test_support.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>

namespace vmsim::program::gcode_test {
namespace {

const fs::path kData = fs::path(VMSIM_SHARED_DIR) / "data" / "gcode";

#define SKIP_WITHOUT_SHARED_DATA()                                 \
  if (!fs::exists(kData))                                          \
  GTEST_SKIP() << "reference data not found at " << kData.string() \
               << " (../shared/data is written outside the project; a fresh clone does not have it)"

struct ReferenceLine {
  std::string n_word;  // "N....." or "N30"
  std::string text;
};

// rs274 -g prints "%5d " then the N column (7 characters, or an N word running into the call) then the call.
std::vector<ReferenceLine> read_reference(const fs::path& path) {
  std::ifstream in(path);
  std::vector<ReferenceLine> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.size() < 7) continue;
    std::string rest = line.substr(6);
    ReferenceLine r;
    if (rest.rfind("N.....", 0) == 0) {
      r.n_word = "N.....";
      rest = rest.substr(6);
    } else {
      std::size_t k = 1;
      while (k < rest.size() && std::isdigit(static_cast<unsigned char>(rest[k]))) ++k;
      r.n_word = rest.substr(0, k);
      rest = rest.substr(k);
    }
    const std::size_t start = rest.find_first_not_of(' ');
    r.text = start == std::string::npos ? "" : rest.substr(start);
    out.push_back(r);
  }
  return out;
}

struct Comparison {
  std::size_t motion_calls = 0;
  std::size_t all_calls = 0;
  double max_diff = 0.0;
};

// Motion calls: same sequence, same names, every number within 1e-4. Every other call: the same text
// (numbers within 1e-4 too) and the same N column.
// (void, so that ASSERT_* can stop it; the counts go to `cmp`)
void compare_with_reference(Comparison& cmp, const std::string& program, const std::string& tool_table,
                            std::vector<int> no_motion = {}) {
  GcodeOptions options;
  options.tool_table = kData / "tooltables" / tool_table;
  options.no_motion_mcodes = std::move(no_motion);
  const GcodeResult mine = interpret_gcode(kData / "programs" / program, options);
  const std::vector<ReferenceLine> ref = read_reference(kData / "rs274_canon" / (program + ".canon.txt"));

  std::vector<Call> ref_motion, my_motion;
  for (const ReferenceLine& r : ref)
    if (Call c = parse_call(r.text); is_motion(c.name)) ref_motion.push_back(c);
  my_motion = motions(mine);
  EXPECT_EQ(my_motion.size(), ref_motion.size()) << program << ": number of motion calls";
  const std::size_t n = std::min(my_motion.size(), ref_motion.size());
  for (std::size_t i = 0; i < n; ++i) {
    const Call& a = my_motion[i];
    const Call& b = ref_motion[i];
    ASSERT_EQ(a.name, b.name) << program << ": motion call " << i + 1 << ": " << a.text << " vs " << b.text;
    ASSERT_EQ(a.numbers.size(), b.numbers.size()) << program << ": motion call " << i + 1;
    for (std::size_t k = 0; k < a.numbers.size(); ++k) {
      const double d = std::fabs(a.numbers[k] - b.numbers[k]);
      cmp.max_diff = std::max(cmp.max_diff, d);
      EXPECT_LE(d, 1e-4) << program << ": motion call " << i + 1 << ": " << a.text << " vs " << b.text;
    }
  }
  cmp.motion_calls = n;

  EXPECT_EQ(mine.canon.size(), ref.size()) << program << ": number of canonical calls";
  const std::size_t m = std::min(mine.canon.size(), ref.size());
  for (std::size_t i = 0; i < m; ++i) {
    const Call a = parse_call(mine.canon[i].text);
    const Call b = parse_call(ref[i].text);
    EXPECT_EQ(mine.canon[i].n_word, ref[i].n_word) << program << ": call " << i + 1 << " N column";
    ASSERT_EQ(a.name, b.name) << program << ": call " << i + 1 << ": " << a.text << " vs " << b.text;
    if (a.numbers.empty() && b.numbers.empty()) {
      EXPECT_EQ(a.text, b.text) << program << ": call " << i + 1;
    } else {
      ASSERT_EQ(a.numbers.size(), b.numbers.size()) << program << ": call " << i + 1 << ": " << a.text;
      for (std::size_t k = 0; k < a.numbers.size(); ++k) {
        const double d = std::fabs(a.numbers[k] - b.numbers[k]);
        cmp.max_diff = std::max(cmp.max_diff, d);
        EXPECT_LE(d, 1e-4) << program << ": call " << i + 1 << ": " << a.text << " vs " << b.text;
      }
    }
  }
  cmp.all_calls = m;
  std::cout << "[ compared ] " << program << ": " << cmp.motion_calls << " motion calls, " << cmp.all_calls
            << " canonical calls in all, max |difference| = " << cmp.max_diff << "\n";
  ::testing::Test::RecordProperty("motion_calls", static_cast<int>(cmp.motion_calls));
  ::testing::Test::RecordProperty("canonical_calls", static_cast<int>(cmp.all_calls));
}

TEST(GcodeReference, TortHelicesInAllPlanesMatchRs274) {
  SKIP_WITHOUT_SHARED_DATA();
  Comparison c;
  compare_with_reference(c, "tort.ngc", "tool_common.tbl");
  EXPECT_GT(c.motion_calls, 260u);
}

TEST(GcodeReference, ThreeDChipsExpressionsMatchRs274) {
  SKIP_WITHOUT_SHARED_DATA();
  Comparison c;
  compare_with_reference(c, "3D_Chips.ngc", "tool_common.tbl");
  EXPECT_GT(c.motion_calls, 4600u);
}

TEST(GcodeReference, BoatFiveAxisInverseTimeMatchesRs274) {
  SKIP_WITHOUT_SHARED_DATA();
  // rs274 ran without the two remapped M428/M429 lines; vmsim accepts them as no-motion codes.
  Comparison c;
  compare_with_reference(c, "boat-xyzac.ngc", "xyzac-trt.tbl", {428, 429});
  EXPECT_GT(c.motion_calls, 1800u);
}

TEST(GcodeReference, BoatWithoutTheRemapIsRefusedAtTheM428Line) {
  SKIP_WITHOUT_SHARED_DATA();
  try {
    interpret_gcode(kData / "programs" / "boat-xyzac.ngc");
    FAIL() << "M428 must be refused unless declared as a no-motion code";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("boat-xyzac.ngc:2: M428"), std::string::npos) << e.what();
  }
}

TEST(GcodeReference, CutterCompensationIsRefusedNamingFileLineAndWord) {
  SKIP_WITHOUT_SHARED_DATA();
  GcodeOptions options;
  options.tool_table = kData / "tooltables" / "tool_common.tbl";
  try {
    interpret_gcode(kData / "programs" / "comp.ngc", options);
    FAIL() << "comp.ngc uses G42/G41, which vmsim must refuse";
  } catch (const core::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("comp.ngc:12: G42 (cutter radius compensation) is not supported"), std::string::npos) << msg;
  }
}

TEST(GcodeReference, ThreeDChipsIsInterpretedQuickly) {
  SKIP_WITHOUT_SHARED_DATA();
  GcodeOptions options;
  options.tool_table = kData / "tooltables" / "tool_common.tbl";
  double best_ms = 1e9;
  for (int i = 0; i < 3; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const GcodeResult r = interpret_gcode(kData / "programs" / "3D_Chips.ngc", options);
    const auto t1 = std::chrono::steady_clock::now();
    best_ms = std::min(best_ms, std::chrono::duration<double, std::milli>(t1 - t0).count());
    ASSERT_GT(r.path.moves.size(), 4600u);
  }
  std::cout << "[ timing   ] 3D_Chips.ngc interpreted in " << best_ms << " ms (best of 3)\n";
  ::testing::Test::RecordProperty("3d_chips_ms", std::to_string(best_ms));
  EXPECT_LT(best_ms, 100.0);
}

TEST(GcodeReference, ThreeDChipsToolPathIsMetricWithTheTableDiameter) {
  SKIP_WITHOUT_SHARED_DATA();
  GcodeOptions options;
  options.tool_table = kData / "tooltables" / "tool_common.tbl";
  const GcodeResult r = interpret_gcode(kData / "programs" / "3D_Chips.ngc", options);
  ASSERT_FALSE(r.path.moves.empty());
  // T1 has D0.125 in the table; the table is in the machine's units (mm for vmsim's machines).
  EXPECT_DOUBLE_EQ(r.path.tool_diameter_mm, 0.125);
  const core::Move& first = r.path.moves.front();  // N90 G0 Z10 (from the origin)
  EXPECT_TRUE(first.rapid);
  EXPECT_EQ(first.source_line, 21);
  EXPECT_DOUBLE_EQ(first.end[core::kZ], 10.0);
  const core::Move& feed = r.path.moves[2];  // N100 G1 Z-25.372 F1000000
  EXPECT_FALSE(feed.rapid);
  EXPECT_DOUBLE_EQ(feed.feed_mm_per_min, 1'000'000.0);
  EXPECT_EQ(feed.tool_number, 1);
  for (std::size_t i = 1; i < r.path.moves.size(); ++i)
    ASSERT_LT((r.path.moves[i].start - r.path.moves[i - 1].end).norm(), 1e-9) << "move " << i;
}

}  // namespace
}  // namespace vmsim::program::gcode_test
