#pragma once
// Units inside vmsim: length mm, time s, angle rad, velocity mm/s (rad/s), current A, torque N·m.
// Files use the trade's units; they are converted once, at load, with these factors.
#include <limits>
#include <numbers>

namespace vmsim::core::units {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kTwoPi = 2 * kPi;
// pi in long double, for the readers that convert angles as LinuxCNC does (in long double).
inline constexpr long double kPiLong = std::numbers::pi_v<long double>;
inline constexpr double kDegToRad = kPi / 180.0;
inline constexpr double kRadToDeg = 180.0 / kPi;
inline constexpr double kInchToMm = 25.4;
inline constexpr double kMmPerMinToMmPerS = 1.0 / 60.0;
inline constexpr double kMPerMinToMmPerS = 1000.0 / 60.0;
inline constexpr double kMPerS2ToMmPerS2 = 1000.0;
inline constexpr double kMPerS3ToMmPerS3 = 1000.0;
// Position-loop gain: 1 (m/min)/mm = 1000/60 1/s = 16.667 1/s.
inline constexpr double kKvMPerMinPerMmToPerS = 1000.0 / 60.0;

// Not units, but shared by the numeric code: defined once, so that no two files define it (unity builds put
// several files in one translation unit).
inline constexpr double kInf = std::numeric_limits<double>::infinity();
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace vmsim::core::units
