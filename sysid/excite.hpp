#pragma once
// Excitation signals for identifying an axis (the predictive-compensation paper section 2.3, eq. 8-15): a pseudo-random
// binary sequence (the M-sequence of an n-bit shift register with maximal-length feedback) or the inverse M-sequence
// (the M-sequence XOR a square wave of period 2, which cancels its DC component), switching at most every Td, amplitude
// +-a, optionally superimposed on a constant velocity so the axis never reverses and Coulomb friction stays a constant
// offset (which the velocity loop's integral action absorbs) instead of a non-linearity.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace vmsim::sysid {

// The predictive-compensation paper eq. 8: m(k) = C1 m(k-1) xor ... xor Cn m(k-n) with the feedback taps of a primitive
// polynomial of degree n (2 <= n <= 20; the table is the one of Xilinx XAPP052, "Efficient Shift Registers, LFSR
// Counters, and Long Pseudo-Random Sequence Generators"), register started at all ones. One period: 2^n - 1 bits (0/1).
std::vector<int> m_sequence(int bits);
// Eq. 9: im(k) = m(k) xor S(k), S = 0 1 0 1 ...: period 2 (2^n - 1) bits, as many ones as zeros.
std::vector<int> inverse_m_sequence(int bits);

// Eq. 14-15: the switching interval Td = q Te whose signal bandwidth 0.433 / Td covers the axis bandwidth B (the
// largest whole q >= 1 with 0.433 / (q Te) >= B).
int switch_samples_for_bandwidth(double bandwidth_hz, double period_s);
// Eq. 11-12: the smallest n whose period 2 (2^n - 1) Td (inverse M) or (2^n - 1) Td (PRBS) resolves `resolution_hz`.
int bits_for_resolution(double resolution_hz, double switch_s, bool inverse);

enum class ExcitationSignal { Prbs, InverseM };

struct ExcitationSpec {
  ExcitationSignal signal = ExcitationSignal::InverseM;
  int bits = 7;             // register length n
  double amplitude = 0.05;  // a: the signal is +-a about the ramp (axis units: mm or rad); eq. 13: a <= travel / 2
  int switch_samples = 4;   // Td / Te
  double period_s = 1e-3;   // Te
  int periods = 4;          // signal periods (the identification uses the first half, validates on the second)
  double velocity = 0.0;    // constant velocity the signal rides on (axis units/s; 0: about a fixed point)
  double start = 0.0;       // position at rest before the signal (axis units)
  double rest_s = 0.1;      // at rest before and after
  double ramp_s = 0.1;      // velocity ramps (raised cosine) from and to rest when velocity != 0
};

// The excitation as setpoints every Te (axis units), at rest at both ends. Throws core::Error for parameters out of
// range (bits, non-positive amplitude, Td, periods).
Eigen::VectorXd excitation_setpoints(const ExcitationSpec& spec);

// The same signal as a G-code program for the machine's NC: one G1 per switching instant (the NC's interpolator then
// shapes it, as the predictive-compensation paper section 3 notes), feeds in mm/min (deg/min for rotary axes: `rotary`
// converts the rad of the spec), G4 dwells where the axis holds still. `header` lines are written as comments.
std::string excitation_gcode(const ExcitationSpec& spec, const std::string& axis_name, bool rotary,
                             const std::vector<std::string>& header);

}  // namespace vmsim::sysid
