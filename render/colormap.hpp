#pragma once
// The diverging colour map of deviation pictures, as plain functions: the pictures and their tests use the same
// definition, so a test can say which colour a pixel over a known deviation must have.
#include <array>
#include <span>

namespace vmsim::render {

using Rgb = std::array<double, 3>;  // 0..1, sRGB

// Blue - white - red (ColorBrewer RdBu, 11 classes, reversed; linear in sRGB between its points): t = -1 is dark
// blue (overcut: the surface below its reference), 0 white, +1 dark red (undercut: material left). t is clamped to
// [-1, 1]. The pictures draw it through a 256-entry table, colour k covering t in [-1 + 2k/256, -1 + 2(k+1)/256).
Rgb diverging_colour(double t);

// Number of entries of that table.
inline constexpr int kColourTableSize = 256;

// The colour the table gives a value v for symmetric limits +-limit: the table entry v falls in.
Rgb table_colour(double v, double limit);

// Symmetric colour limits for deviations: max |v| over the finite values (not a percentile: a simulated mark is a
// few per mille of the surface and its deepest point is the figure that matters), rounded up to 1, 2, 2.5 or 5
// x 10^k so that the scale's labels are round; never below `floor`. NaN values are ignored.
double symmetric_limit(std::span<const double> values, double floor);

// The smallest of 1, 2, 2.5, 5 x 10^k that is >= x (x > 0).
double nice_ceil(double x);

}  // namespace vmsim::render
