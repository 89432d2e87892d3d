// Feed plans as files (methods/feedplan_file, vmsim plan-feed's feed_plan.csv, [job] feed_plan). References: IEEE
// round trip of 17 significant digits (the ceiling read back bit for bit); the circle's own equation for the points
// written (x^2 + y^2 = R^2, the quintic chain within 10 nm of it); and the rule of DESIGN.md that a file for another
// path or period is refused with a message naming the file (and its line).
#include "tests/app/cli_util.hpp"
#include "core/error.hpp"
#include "methods/feedplan_file.hpp"
#include "motion/nurbs.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

using vmsim_test::TempDir;  // tests/app/cli_util.hpp

// A circle of radius r about (cx, cy) as a rational quadratic NURBS, and the G2 chain the interpolator follows.
motion::SmoothPath circle_path(double r, double cx = 0.0, double cy = 0.0) {
  motion::NurbsCurve n;
  n.degree = 2;
  const double w = std::sqrt(0.5);
  const double xs[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, ys[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
  for (int i = 0; i < 9; ++i) {
    n.points.emplace_back(cx + r * xs[i], cy + r * ys[i], 0);
    n.weights.push_back(i % 2 ? w : 1.0);
  }
  n.knots = {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1};
  return motion::nurbs_to_path(n).path;
}

// A ceiling every 0.37 mm that varies along the path (values with no short decimal form).
motion::FeedCeiling ceiling_along(const motion::SmoothPath& p) {
  motion::FeedCeiling c;
  for (double s = 0.0; s < p.length; s += 0.37) {
    c.s_mm.push_back(s);
    c.feed_mm_per_s.push_back(30.0 + 17.0 * std::sin(s / 7.0) + 1.0 / 3.0);
  }
  c.s_mm.push_back(p.length);
  c.feed_mm_per_s.push_back(c.feed_mm_per_s.back());
  return c;
}

std::string read_error(const fs::path& file, const motion::SmoothPath& path, double te) {
  try {
    methods::read_feed_plan(file, path, te);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(FeedPlanFile, RoundTripIsExactAndThePointsLieOnThePath) {
  TempDir tmp;
  const motion::SmoothPath path = circle_path(20.0);
  const motion::FeedCeiling c = ceiling_along(path);
  const fs::path f = tmp.path() / "feed_plan.csv";
  methods::write_feed_plan(f, c, path, 0.004, "circle", {"a comment"});
  const motion::FeedCeiling back = methods::read_feed_plan(f, path, 0.004);
  ASSERT_EQ(back.s_mm.size(), c.s_mm.size());
  for (std::size_t i = 0; i < c.s_mm.size(); ++i) {
    EXPECT_EQ(back.s_mm[i], c.s_mm[i]) << i;
    EXPECT_EQ(back.feed_mm_per_s[i], c.feed_mm_per_s[i]) << i;
  }
  // The points written are the circle's (the chain keeps within 10 nm of the curve, the file has 1 nm).
  std::istringstream in(slurp(f));
  std::string line;
  int points = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line[0] == 's') continue;
    double s, v, x, y, z;
    char comma;
    std::istringstream l(line);
    l >> s >> comma >> v >> comma >> x >> comma >> y >> comma >> z;
    EXPECT_NEAR(std::hypot(x, y), 20.0, 2e-5) << line;
    EXPECT_EQ(z, 0.0);
    ++points;
  }
  EXPECT_EQ(points, static_cast<int>(c.s_mm.size()));
  EXPECT_NE(slurp(f).find("# a comment\n"), std::string::npos);
  EXPECT_NEAR(path.length, 2 * M_PI * 20.0, 1e-4);  // the circumference: the path is the circle's
}

// A profile to be followed (motion::FeedCeiling::follow) keeps its mark and its zero feeds (the ends at rest, one
// cusp between) through the file, bit for bit; a ceiling's file has no follow line, and a zero feed without the mark
// is refused naming the file and the line.
TEST(FeedPlanFile, AFollowedProfileKeepsItsMarkAndItsZeroFeeds) {
  TempDir tmp;
  const motion::SmoothPath path = circle_path(20.0);
  motion::FeedCeiling c = ceiling_along(path);
  c.s_mm.front() = 0.0;
  c.s_mm.back() = path.length;
  c.feed_mm_per_s.front() = c.feed_mm_per_s.back() = c.feed_mm_per_s[c.s_mm.size() / 2] = 0.0;
  c.follow = true;
  const fs::path f = tmp.path() / "profile.csv";
  methods::write_feed_plan(f, c, path, 0.004, "circle");
  EXPECT_NE(slurp(f).find("\n# follow=1\n"), std::string::npos);
  const motion::FeedCeiling back = methods::read_feed_plan(f, path, 0.004);
  EXPECT_TRUE(back.follow);
  ASSERT_EQ(back.s_mm.size(), c.s_mm.size());
  for (std::size_t i = 0; i < c.s_mm.size(); ++i) {
    EXPECT_EQ(back.s_mm[i], c.s_mm[i]) << i;
    EXPECT_EQ(back.feed_mm_per_s[i], c.feed_mm_per_s[i]) << i;
  }
  const fs::path g = tmp.path() / "ceiling.csv";
  methods::write_feed_plan(g, ceiling_along(path), path, 0.004, "circle");
  EXPECT_EQ(slurp(g).find("# follow="), std::string::npos);
  std::string text = slurp(f);
  text.replace(text.find("# follow=1\n"), 11, "");
  std::ofstream(tmp.path() / "unmarked.csv") << text;
  try {
    methods::read_feed_plan(tmp.path() / "unmarked.csv", path, 0.004);
    FAIL() << "a zero feed without the follow mark was taken";
  } catch (const core::Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("unmarked.csv"), std::string::npos) << m;
    EXPECT_NE(m.find("expected > 0"), std::string::npos) << m;
  }
}

TEST(FeedPlanFile, APlanForAnotherPathOrPeriodIsRefusedNamingTheFile) {
  TempDir tmp;
  const motion::SmoothPath path = circle_path(20.0);
  const fs::path f = tmp.path() / "plan.csv";
  methods::write_feed_plan(f, ceiling_along(path), path, 0.004, "circle");
  {
    const std::string e = read_error(f, path, 0.001);  // another interpolation period
    EXPECT_NE(e.find(f.string()), std::string::npos) << e;
    EXPECT_NE(e.find("Te"), std::string::npos) << e;
  }
  {
    const std::string e = read_error(f, circle_path(21.0), 0.004);  // another length
    EXPECT_NE(e.find(f.string()), std::string::npos) << e;
    EXPECT_NE(e.find("another program, curve or tolerance"), std::string::npos) << e;
  }
  {
    // The same length elsewhere: the points tell. The first data line (after 5 '#' lines and the header) is line 7.
    const std::string e = read_error(f, circle_path(20.0, 1.0, 0.0), 0.004);
    EXPECT_NE(e.find(f.string() + ":7:"), std::string::npos) << e;
    EXPECT_NE(e.find("another path"), std::string::npos) << e;
  }
}

TEST(FeedPlanFile, MalformedFilesAreErrorsNamingTheLine) {
  TempDir tmp;
  const motion::SmoothPath path = circle_path(20.0);
  const fs::path f = tmp.path() / "plan.csv";
  methods::write_feed_plan(f, ceiling_along(path), path, 0.004, "circle");
  const std::string good = slurp(f);
  auto with = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const auto i = t.find(from);
    EXPECT_NE(i, std::string::npos) << from;
    if (i != std::string::npos) t.replace(i, from.size(), to);
    const fs::path g = tmp.path() / "bad.csv";
    std::ofstream(g) << t;
    return read_error(g, path, 0.004);
  };
  const std::string bad = (tmp.path() / "bad.csv").string();
  EXPECT_NE(with("# vmsim feed plan 1", "# a gain schedule").find(bad + ":1:"), std::string::npos);
  EXPECT_NE(with("s_mm,feed_ceiling", "s,feed").find("column header"), std::string::npos);
  EXPECT_NE(with("# points=", "# pointz=").find("# points="), std::string::npos);
  // The second data line (line 8) repeats the first's s; then a ceiling of 0 on the first (line 7).
  const std::size_t l7 = good.find('\n', good.find("z_mm")) + 1, l8 = good.find('\n', l7) + 1;
  const std::string first = good.substr(l7, l8 - l7), second = good.substr(l8, good.find('\n', l8) + 1 - l8);
  {
    const std::string e = with(second, first);
    EXPECT_NE(e.find(bad + ":8:"), std::string::npos) << e;
    EXPECT_NE(e.find("larger than"), std::string::npos) << e;
  }
  {
    std::string zero = first;
    zero.replace(zero.find(','), zero.find(',', zero.find(',') + 1) - zero.find(','), ",0");
    const std::string e = with(first, zero);
    EXPECT_NE(e.find(bad + ":7:"), std::string::npos) << e;
    EXPECT_NE(e.find("expected > 0"), std::string::npos) << e;
  }
  EXPECT_NE(with(second, "").find("points, the header announces"), std::string::npos);
  EXPECT_NE(read_error(tmp.path() / "none.csv", path, 0.004).find("cannot open"), std::string::npos);
}
