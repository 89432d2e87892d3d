#pragma once
// Units inside vmsim: length mm, time s, angle rad, velocity mm/s (rad/s), current A, torque N·m.
// Files use the trade's units; they are converted once, at load, with these factors.
#include <numbers>

namespace vmsim::core::units {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kDegToRad = kPi / 180.0;
inline constexpr double kRadToDeg = 180.0 / kPi;
inline constexpr double kInchToMm = 25.4;
inline constexpr double kMmPerMinToMmPerS = 1.0 / 60.0;
inline constexpr double kMPerMinToMmPerS = 1000.0 / 60.0;
inline constexpr double kMPerS2ToMmPerS2 = 1000.0;
inline constexpr double kMPerS3ToMmPerS3 = 1000.0;
// Position-loop gain: 1 (m/min)/mm = 1000/60 1/s = 16.667 1/s.
inline constexpr double kKvMPerMinPerMmToPerS = 1000.0 / 60.0;

}  // namespace vmsim::core::units
