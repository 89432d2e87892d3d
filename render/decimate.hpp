#pragma once
// A line's points reduced to what a raster of a given width can show: per pixel column, the first, lowest, highest
// and last point of each run of consecutive points in that column (the M4 aggregation of Jugel et al., "M4: a
// visualization-oriented time series data aggregation", VLDB 2014). Drawn as a polyline, the result covers the same
// pixels as the whole line: within a column it spans the same lowest..highest, and it enters and leaves the column
// where the line does.
#include <Eigen/Core>

namespace vmsim::render {

struct Polyline {
  Eigen::ArrayXd x, y;
};

// Points of (x, y) in order, reduced per column of `columns` equal columns over [x_lo, x_hi] (points outside it
// fall into columns beyond its ends, grouped the same way). A point with a non-finite x or y breaks the line: it is
// kept as one NaN point between the runs on either side (consecutive breaks become one). The kept points are
// original points, in their original order. Throws core::Error unless x and y have the same length, columns >= 1
// and x_lo < x_hi (both finite).
Polyline column_envelope(const Eigen::ArrayXd& x, const Eigen::ArrayXd& y, double x_lo, double x_hi, int columns);

}  // namespace vmsim::render
