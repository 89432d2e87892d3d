#pragma once
// Lengths between files and vmsim. Surface files state lengths in metres (X3P, SDF) or in a unit they name (.sur,
// ASCII grids); vmsim works in mm. Converting a decimal text by multiplying its parsed value by 1000 rounds twice
// and loses the last bit about once in seventy values, so conversions here shift the decimal exponent of the text
// itself and round once: "5.0000000000000003E-5" m is read as the double nearest to 5.0000000000000003E-2 mm.
// Written numbers use the shortest digits that give the double back (std::to_chars), with the exponent shifted
// the other way, so text written by vmsim reads back bit for bit.
#include <optional>
#include <string>
#include <string_view>

namespace vmsim::metrology {

// Parses a decimal number ([+-]digits[.digits][(e|E)[+-]digits], surrounding blanks allowed) and returns the
// double nearest to value * 10^shift10. "nan", "inf" and anything else are rejected (nullopt).
std::optional<double> parse_decimal_scaled(std::string_view text, int shift10 = 0);

// The shortest decimal digits of v that read back as v, written as d.dddE+x with the exponent raised by shift10
// (format_scaled(0.05, -3) == "5E-05"). NaN and infinities are written as "NaN", "INF", "-INF".
std::string format_scaled(double v, int shift10 = 0);

// Powers of ten of length unit names as instruments write them: m 0, cm -2, mm -3, um/µm/μm/micron -6, nm -9,
// pm -12, A (angstrom) -10; case-sensitive except for a trailing dot or blanks. nullopt for anything else.
std::optional<int> length_unit_pow10(std::string_view unit);

}  // namespace vmsim::metrology
