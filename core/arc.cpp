#include "core/arc.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace vmsim::core {

namespace {

constexpr double kTwoPi = 2.0 * units::kPi;

}  // namespace

PlaneAxes plane_axes(ArcPlane plane) {
  switch (plane) {
    case ArcPlane::XY:
      return {kX, kY, kZ};
    case ArcPlane::ZX:
      return {kZ, kX, kY};
    case ArcPlane::YZ:
      return {kY, kZ, kX};
  }
  return {};
}

ArcFrame arc_frame(const Move& m, const std::string& file) {
  ArcFrame a;
  const PlaneAxes ax = plane_axes(m.plane);
  a.axis1 = ax.axis1, a.axis2 = ax.axis2, a.normal = ax.normal;
  a.start = m.start;
  a.end = m.end;
  a.centre_mm = m.centre_mm;
  const double c1 = m.centre_mm[0], c2 = m.centre_mm[1];
  const Vec6& s = m.start;
  const Vec6& e = m.end;
  a.start_radius_mm = std::hypot(s[a.axis1] - c1, s[a.axis2] - c2);
  a.end_radius_mm = std::hypot(e[a.axis1] - c1, e[a.axis2] - c2);
  if (!(a.start_radius_mm > 1e-9) || !(a.end_radius_mm > 1e-9) || m.rotation == 0)
    throw Error(located(file.empty() ? "program" : file, m.source_line, "arc with zero radius or no direction"));
  a.start_angle_rad = std::atan2(s[a.axis2] - c2, s[a.axis1] - c1);
  const double te = std::atan2(e[a.axis2] - c2, e[a.axis1] - c1);
  a.extra_turns = std::abs(m.rotation) - 1;
  a.full_circle =
      std::hypot(e[a.axis1] - s[a.axis1], e[a.axis2] - s[a.axis2]) < 1e-9 * std::max(1.0, a.start_radius_mm);
  // The angle from start to end in the direction of rotation, in [0, 2 pi), and a whole turn for coinciding points
  // or an end on the start's ray (within 1e-12 rad: an equal-radius arc that short is a coinciding point already), as
  // LinuxCNC's pmCircleInit and its interpreter's find_turn make it.
  double sweep = m.rotation > 0 ? std::fmod(te - a.start_angle_rad + 2 * kTwoPi, kTwoPi)
                                : std::fmod(a.start_angle_rad - te + 2 * kTwoPi, kTwoPi);
  if (a.full_circle || sweep < 1e-12) sweep = kTwoPi;
  sweep += a.extra_turns * kTwoPi;
  a.sweep_rad = m.rotation > 0 ? sweep : -sweep;
  return a;
}

bool ArcFrame::constant_radius() const { return std::abs(end_radius_mm - start_radius_mm) <= 1e-12 * start_radius_mm; }

Vec6 ArcFrame::point_at(double f) const {
  if (f <= 0) return start;
  if (f >= 1) return end;
  Vec6 p = start + f * (end - start);
  const double th = angle_at(f), r = radius_at(f);
  p[axis1] = centre_mm[0] + r * std::cos(th);
  p[axis2] = centre_mm[1] + r * std::sin(th);
  return p;
}

Eigen::Vector3d ArcFrame::tangent_at(double f) const {
  Eigen::Vector3d d = (end - start).head<3>();
  const double th = angle_at(f), r = radius_at(f), dr = end_radius_mm - start_radius_mm;
  const double c = std::cos(th), s = std::sin(th);
  d[axis1] = dr * c - r * sweep_rad * s;
  d[axis2] = dr * s + r * sweep_rad * c;
  return d;
}

double ArcFrame::length_mm() const {
  const double dw = end[normal] - start[normal];
  if (constant_radius()) return std::hypot(start_radius_mm * sweep_rad, dw);
  // A spiral: the speed sqrt(dr^2 + dw^2 + (r(f) sweep)^2) does not oscillate with the turns; it is analytic but for
  // r(f) = 0, outside [0, 1] at a distance min(r0, r1) / |dr| or more. Gauss-Legendre (8 points) on pieces an eighth
  // of that distance long converges to rounding.
  static constexpr std::array<double, 4> kX8 = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267,
                                                0.9602898564975363};
  static constexpr std::array<double, 4> kW8 = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745,
                                                0.1012285362903763};
  const double dr = end_radius_mm - start_radius_mm, a2 = dr * dr + dw * dw;
  const double pieces = std::ceil(8 * std::abs(dr) / std::min(start_radius_mm, end_radius_mm));
  const int n = static_cast<int>(std::clamp(pieces, 1.0, 1e5));
  auto speed = [&](double f) {
    const double rw = radius_at(f) * sweep_rad;
    return std::sqrt(a2 + rw * rw);
  };
  double len = 0;
  for (int k = 0; k < n; ++k) {
    const double mid = (k + 0.5) / n, half = 0.5 / n;
    double piece = 0;
    for (std::size_t i = 0; i < kX8.size(); ++i)
      piece += kW8[i] * (speed(mid - half * kX8[i]) + speed(mid + half * kX8[i]));
    len += piece * half;
  }
  return len;
}

int ArcFrame::chords(double sag_mm, double max_angle_rad) const {
  double step = max_angle_rad > 0 ? max_angle_rad
                                  : 2 * std::acos(std::max(0.0, 1 - sag_mm / std::max(start_radius_mm, end_radius_mm)));
  step = std::max(step, 1e-6);
  const double n = std::ceil(std::abs(sweep_rad) / step);
  if (!(n <= 1e8))
    throw Error(fmt::format("an arc of {:g} rad at radius {:g} mm needs {:g} chords within {:g} mm (at most 1e8)",
                            std::abs(sweep_rad), std::max(start_radius_mm, end_radius_mm), n, sag_mm));
  return std::max(1, static_cast<int>(n));
}

}  // namespace vmsim::core
