#include "sysid/excite.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <cmath>

namespace vmsim::sysid {

namespace {

// Taps (exponents of the primitive feedback polynomial) per register length; XAPP052 Table 3.
const std::vector<std::vector<int>>& taps_table() {
  static const std::vector<std::vector<int>> t = {{},
                                                  {},
                                                  {2, 1},
                                                  {3, 2},
                                                  {4, 3},
                                                  {5, 3},
                                                  {6, 5},
                                                  {7, 6},
                                                  {8, 6, 5, 4},
                                                  {9, 5},
                                                  {10, 7},
                                                  {11, 9},
                                                  {12, 6, 4, 1},
                                                  {13, 4, 3, 1},
                                                  {14, 5, 3, 1},
                                                  {15, 14},
                                                  {16, 15, 13, 4},
                                                  {17, 14},
                                                  {18, 11},
                                                  {19, 6, 2, 1},
                                                  {20, 17}};
  return t;
}

void check_bits(int bits) {
  if (bits < 2 || bits > 20)
    throw core::Error(fmt::format("excitation: register bits n must be in [2, 20], found {}", bits));
}

}  // namespace

std::vector<int> m_sequence(int bits) {
  check_bits(bits);
  const std::vector<int>& taps = taps_table()[static_cast<std::size_t>(bits)];
  // reg[i] holds m(k - 1 - i).
  std::vector<int> reg(static_cast<std::size_t>(bits), 1);
  const std::size_t len = (std::size_t{1} << bits) - 1;
  std::vector<int> out(len);
  for (std::size_t k = 0; k < len; ++k) {
    int next = 0;
    for (int t : taps) next ^= reg[static_cast<std::size_t>(t - 1)];
    out[k] = next;
    for (std::size_t i = reg.size() - 1; i > 0; --i) reg[i] = reg[i - 1];
    reg[0] = next;
  }
  return out;
}

std::vector<int> inverse_m_sequence(int bits) {
  const std::vector<int> m = m_sequence(bits);
  std::vector<int> out(2 * m.size());
  for (std::size_t k = 0; k < out.size(); ++k) out[k] = m[k % m.size()] ^ static_cast<int>(k & 1u);
  return out;
}

int switch_samples_for_bandwidth(double bandwidth_hz, double period_s) {
  if (!(bandwidth_hz > 0.0) || !(period_s > 0.0))
    throw core::Error(
        fmt::format("excitation: bandwidth ({} Hz) and period ({} s) must be positive", bandwidth_hz, period_s));
  const int q = static_cast<int>(std::floor(0.433 / (bandwidth_hz * period_s) + 1e-9));
  return q < 1 ? 1 : q;
}

int bits_for_resolution(double resolution_hz, double switch_s, bool inverse) {
  if (!(resolution_hz > 0.0) || !(switch_s > 0.0))
    throw core::Error(
        fmt::format("excitation: resolution ({} Hz) and Td ({} s) must be positive", resolution_hz, switch_s));
  for (int n = 2; n <= 20; ++n) {
    const double period = (inverse ? 2.0 : 1.0) * (std::ldexp(1.0, n) - 1.0) * switch_s;
    if (1.0 / period <= resolution_hz) return n;
  }
  throw core::Error(fmt::format("excitation: a resolution of {} Hz needs more than 20 register bits", resolution_hz));
}

namespace {

void check_spec(const ExcitationSpec& s) {
  check_bits(s.bits);
  if (!(s.amplitude > 0.0 && std::isfinite(s.amplitude)))
    throw core::Error(fmt::format("excitation: the amplitude must be positive, found {}", s.amplitude));
  if (s.switch_samples < 1)
    throw core::Error(fmt::format("excitation: Td must be at least one Te, found {} samples", s.switch_samples));
  if (!(s.period_s > 0.0)) throw core::Error("excitation: the sampling period Te must be positive");
  if (s.periods < 1 || s.periods > 1000)
    throw core::Error(fmt::format("excitation: periods must be in [1, 1000], found {}", s.periods));
  if (!std::isfinite(s.velocity)) throw core::Error("excitation: the velocity is not finite");
  if (!(s.rest_s >= 0.0) || !(s.ramp_s >= 0.0)) throw core::Error("excitation: rest and ramp times must be >= 0");
}

std::vector<int> bits_of(const ExcitationSpec& s) {
  return s.signal == ExcitationSignal::InverseM ? inverse_m_sequence(s.bits) : m_sequence(s.bits);
}

}  // namespace

Eigen::VectorXd excitation_setpoints(const ExcitationSpec& s) {
  check_spec(s);
  const std::vector<int> seq = bits_of(s);
  const double te = s.period_s;
  const long rest = std::lround(s.rest_s / te);
  const long ramp = s.velocity != 0.0 ? std::lround(s.ramp_s / te) : 0;
  const long body = static_cast<long>(seq.size()) * s.switch_samples * s.periods;
  const long n = rest + ramp + body + ramp + rest + 1;
  Eigen::VectorXd x(n);
  // Velocity profile: 0, raised-cosine ramp up, v, ramp down, 0; the position is its running sum (exact integral of
  // the piecewise-constant velocity per Te).
  double pos = s.start;
  for (long k = 0; k < n; ++k) {
    double v = 0.0;
    const long kb = k - rest;
    if (kb >= 0 && kb < ramp)
      v = s.velocity * 0.5 * (1.0 - std::cos(core::units::kPi * (kb + 0.5) / ramp));
    else if (kb >= ramp && kb < ramp + body)
      v = s.velocity;
    else if (kb >= ramp + body && kb < 2 * ramp + body)
      v = s.velocity * 0.5 * (1.0 + std::cos(core::units::kPi * (kb - ramp - body + 0.5) / ramp));
    double level = 0.0;
    const long ks = k - rest - ramp;
    // The signal starts and ends at 0 (about the ramp) so the axis leaves and reaches rest smoothly: +-a only inside.
    if (ks >= 0 && ks < body)
      level = seq[static_cast<std::size_t>((ks / s.switch_samples) % static_cast<long>(seq.size()))] ? s.amplitude
                                                                                                     : -s.amplitude;
    x[k] = pos + level;
    pos += v * te;
  }
  return x;
}

std::string excitation_gcode(const ExcitationSpec& s, const std::string& axis, bool rotary,
                             const std::vector<std::string>& header) {
  check_spec(s);
  const Eigen::VectorXd x = excitation_setpoints(s);
  const double f = rotary ? core::units::kRadToDeg : 1.0;
  const double te = s.period_s;
  std::string out;
  for (std::string h : header) {
    // G-code comments do not nest: brackets for the parentheses a header line may hold.
    for (char& ch : h) ch = ch == '(' ? '[' : ch == ')' ? ']' : ch;
    out += "(" + h + ")\n";
  }
  out += "G21 G90 G94 G17\n";
  out += fmt::format("G0 {}{:.6f}\n", axis, x[0] * f);
  // A block every Td, on the switching grid of the signal (the level changes at its start), and one to the end; a
  // block that does not move is a dwell.
  const long offset = std::lround(s.rest_s / te) + (s.velocity != 0.0 ? std::lround(s.ramp_s / te) : 0);
  long last = 0;
  for (long k = 1; k < x.size(); ++k) {
    const bool boundary = ((k - offset) % s.switch_samples + s.switch_samples) % s.switch_samples == 0;
    if (!boundary && k + 1 != x.size()) continue;
    const double dt = (k - last) * te;
    const double d = std::abs(x[k] - x[last]) * f;
    if (d <= 1e-9)
      out += fmt::format("G4 P{:.4f}\n", dt);
    else
      out += fmt::format("G1 {}{:.6f} F{:.3f}\n", axis, x[k] * f, d / dt * 60.0);
    last = k;
  }
  out += "M2\n";
  return out;
}

}  // namespace vmsim::sysid
