// ray_interval with tilted tools, on the rays a tri-dexel field and needles use (along X, Y and Z, along the tool
// axis and a hair off it, edge-on to a flat end's disk, and in random directions), against the independent
// references of tool_reference.hpp: closed-form ray intervals for tools at rest, and a convex ray solver on the
// exact signed distance for moving tools.
#include "tool_reference.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <string>

using namespace vmsim::removal;
namespace ref = vmsim::removal::testref;

namespace {

using vmsim::removal::test::tool;

struct Stats {
  int rays = 0, hits = 0, grazing = 0;
  double worst_end = 0;  // largest disagreement of an end that is not explained by a grazing ray (mm, along the ray)
};

// The kernel's interval against a reference interval of the same convex set {f <= 0}. Ends agree to 1e-8 mm along
// the ray, or the ray runs within 1e-8 mm of the surface between the two ends (a grazing ray: there the end is
// ill-conditioned for any solver, and either answer describes the same set to 1e-8 mm). A hit one side misses is
// allowed only as such a contact.
void compare(const std::function<double(const Eigen::Vector3d&)>& f, const Eigen::Vector3d& o, const Eigen::Vector3d& u,
             bool hk, double k0, double k1, bool hr, double r0, double r1, double fmin, const std::string& what,
             Stats& st) {
  constexpr double kT = 1e-8, kF = 1e-8;
  ++st.rays;
  auto flat_between = [&](double a, double b) {
    for (int k = 0; k <= 20; ++k)
      if (std::abs(f(o + (a + (b - a) * k / 20.0) * u)) > kF) return false;
    return true;
  };
  if (hk && hr) {
    ++st.hits;
    for (auto [a, b] : {std::pair{k0, r0}, std::pair{k1, r1}}) {
      if (std::abs(a - b) <= kT) {
        st.worst_end = std::max(st.worst_end, std::abs(a - b));
        continue;
      }
      ++st.grazing;
      EXPECT_TRUE(flat_between(a, b)) << what << ": kernel end " << a << ", reference " << b
                                      << " (f at the kernel's end " << f(o + a * u) << ")";
    }
  } else if (hk) {
    ++st.grazing;
    EXPECT_LE(fmin, kF) << what << ": the kernel cuts [" << k0 << ", " << k1 << "] where the reference sees nothing";
    EXPECT_TRUE(flat_between(k0, k1)) << what << ": the kernel's cut [" << k0 << ", " << k1 << "] is not a contact";
  } else if (hr) {
    ++st.grazing;
    EXPECT_GE(fmin, -kF) << what << ": the kernel misses [" << r0 << ", " << r1 << "], depth " << -fmin;
  }
}

// The ray directions of the fields and needles for a tool axis a: the grid axes both ways, the axis and a hair off
// it (the kernel switches to its axial closed form within 1e-12 of the axis), and a random direction.
std::vector<Eigen::Vector3d> directions(const Eigen::Vector3d& a, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<Eigen::Vector3d> d;
  for (int i = 0; i < 3; ++i) {
    d.push_back(Eigen::Vector3d::Unit(i));
    d.push_back(-Eigen::Vector3d::Unit(i));
  }
  d.push_back(a);
  d.push_back(-a);
  const Eigen::Vector3d p = a.unitOrthogonal();
  for (double eps : {1e-13, 1e-11, 1e-9, 1e-7, 1e-5, 1e-3}) d.push_back((a + eps * p).normalized());
  d.push_back(a.cross(p));  // perpendicular to the axis: a flat end's disk edge-on
  d.push_back(Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized());
  return d;
}

// Tool axes: random tilts, tilts in the coordinate planes (so that grid rays are perpendicular to the axis, the
// disk edge-on), the grid axes themselves and axes a hair off them.
Eigen::Vector3d random_axis(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(-1, 1), A(0, 1.4);
  switch (n % 6) {
    case 0:
      return Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized();
    case 1: {
      const double t = A(rng);
      return Eigen::Vector3d(std::sin(t), 0, std::cos(t));
    }
    case 2: {
      const double t = A(rng);
      return Eigen::Vector3d(0, std::cos(t), std::sin(t));
    }
    case 3:
      return Eigen::Vector3d::Unit(n % 3);
    case 4:
      return (Eigen::Vector3d::Unit(n % 3) + std::pow(10.0, -13 + (n % 11)) * Eigen::Vector3d(U(rng), U(rng), U(rng)))
          .normalized();
    default:
      return Eigen::Vector3d(U(rng), U(rng), 2 + U(rng)).normalized();
  }
}

}  // namespace

// A tool at rest (d = 0) in any pose: the kernel's interval equals the textbook capsule / cylinder interval.
TEST(TiltedTool, ToolAtRestMatchesTheClosedForms) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  Stats st;
  for (int n = 0; n < 1200; ++n) {
    SweptTool s;
    s.tool = n % 2 == 0 ? tool(3, 3, 25) : tool(4, 0, 20);
    s.tip0 = Eigen::Vector3d(U(rng), U(rng), U(rng)) * 5;
    s.axis = random_axis(n / 2, rng);
    const auto f = [&](const Eigen::Vector3d& x) { return ref::body_sd(s.tool, s.tip0, s.axis, x); };
    for (const Eigen::Vector3d& u : directions(s.axis, rng)) {
      // Aim at a point of the body's neighbourhood; every few rays exactly at the bottom disk's plane or on the
      // axis, where the flat end is seen edge-on or the ray runs along the axis.
      Eigen::Vector3d target =
          s.tip0 + s.axis * (s.tool.length_mm * 0.5 * (1 + U(rng))) + Eigen::Vector3d(U(rng), U(rng), U(rng)) * 5;
      if (n % 4 == 1) target = s.tip0 + s.axis.cross(u).normalized() * (4 * U(rng));  // in the tip's plane
      if (n % 4 == 3) target = s.tip0 + s.tool.length_mm * s.axis + s.axis.unitOrthogonal() * U(rng);  // top
      if (!target.allFinite()) target = s.tip0 + Eigen::Vector3d(U(rng), U(rng), 0);
      const Eigen::Vector3d o = target - 60 * u;
      double k0 = 0, k1 = 0, r0 = 0, r1 = 0;
      const bool hk = ray_interval(s, o, u, k0, k1);
      const bool hr = ref::body_ray(s.tool, s.tip0, s.axis, o, u, r0, r1);
      double fmin;
      ref::golden([&](double t) { return f(o + t * u); }, 0.0, 120.0, fmin, 1e-15);
      std::ostringstream w;
      w.precision(17);
      w << "case " << n << " u " << u.transpose() << " o " << o.transpose() << " axis " << s.axis.transpose() << " tip "
        << s.tip0.transpose() << " d " << s.d.transpose();
      compare(f, o, u, hk, k0, k1, hr, r0, r1, fmin, w.str(), st);
    }
    if (HasFailure()) break;
  }
  EXPECT_GT(st.hits, st.rays / 3);
  RecordProperty("rays", st.rays);
  RecordProperty("grazing", st.grazing);
  RecordProperty("worst_end_mm", std::to_string(st.worst_end));
  std::printf("[ tilted   ] at rest: %d rays, %d hits, %d grazing ends, worst end %.2e mm\n", st.rays, st.hits,
              st.grazing, st.worst_end);
}

// A tilted tool on a straight move (random, along its axis, across it, in the disk's plane): the kernel's interval
// equals the interval of the convex swept set {min_l sd(x - l d) <= 0}.
TEST(TiltedTool, MovingToolMatchesTheConvexReference) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1, 1);
  Stats st;
  for (int n = 0; n < 300; ++n) {
    SweptTool s;
    s.tool = n % 2 == 0 ? tool(3, 3, 25) : tool(4, 0, 20);
    s.tip0 = Eigen::Vector3d(U(rng), U(rng), U(rng)) * 5;
    s.axis = random_axis(n / 2, rng);
    s.d = Eigen::Vector3d(U(rng), U(rng), U(rng)) * 10;
    if (n % 5 == 1) s.d = 7 * U(rng) * s.axis;                                                     // along the axis
    if (n % 5 == 2) s.d = 8 * s.axis.cross(Eigen::Vector3d(U(rng), U(rng), U(rng))).normalized();  // across it
    if (n % 5 == 3) s.d = Eigen::Vector3d::Unit(n % 3) * 9;                                        // a grid axis
    const auto f = [&](const Eigen::Vector3d& x) { return ref::swept_sd(s.tool, s.tip0, s.axis, s.d, x); };
    std::vector<Eigen::Vector3d> dirs = directions(s.axis, rng);
    for (std::size_t q = 0; q < dirs.size(); q += 1 + (n % 2)) {
      const Eigen::Vector3d& u = dirs[q];
      Eigen::Vector3d target = s.tip0 + (0.5 + 0.5 * U(rng)) * s.d + s.axis * (s.tool.length_mm * 0.5 * (1 + U(rng))) +
                               Eigen::Vector3d(U(rng), U(rng), U(rng)) * 4;
      if (n % 4 == 1) target = s.tip0 + (0.5 + 0.5 * U(rng)) * s.d + s.axis.cross(u).normalized() * (4 * U(rng));
      if (!target.allFinite()) target = s.tip0;
      const Eigen::Vector3d o = target - 60 * u;
      double k0 = 0, k1 = 0, r0 = 0, r1 = 0, fmin;
      const bool hk = ray_interval(s, o, u, k0, k1);
      const bool hr = ref::ray_ref(f, o, u, 0, 120, r0, r1, fmin);
      std::ostringstream w;
      w.precision(17);
      w << "case " << n << " u " << u.transpose() << " o " << o.transpose() << " axis " << s.axis.transpose() << " tip "
        << s.tip0.transpose() << " d " << s.d.transpose();
      compare(f, o, u, hk, k0, k1, hr, r0, r1, fmin, w.str(), st);
    }
    if (HasFailure()) break;
  }
  EXPECT_GT(st.hits, st.rays / 3);
  RecordProperty("rays", st.rays);
  RecordProperty("grazing", st.grazing);
  RecordProperty("worst_end_mm", std::to_string(st.worst_end));
  std::printf("[ tilted   ] moving: %d rays, %d hits, %d grazing ends, worst end %.2e mm\n", st.rays, st.hits,
              st.grazing, st.worst_end);
}
