#pragma once
// Line charts of signals (vtkChartXY in the same headless window): contour error along the path, feed, axis
// velocity / acceleration / jerk against their limits, currents, setpoint against actual position. One picture
// holds one or more charts stacked top to bottom.
#include "render/colormap.hpp"
#include "render/image.hpp"
#include "render/window.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vmsim::render {

struct Series {
  std::string name;     // legend entry
  Eigen::ArrayXd x, y;  // same length; a NaN in x or y breaks the line there
  Rgb colour{0.12, 0.35, 0.70};
  double width = 2.0;  // pixels at 1600 x 900; scaled with the picture
  bool dashed = false;
};

// A horizontal line across the whole chart, e.g. a limit.
struct Level {
  std::string name;  // legend entry ("limit 2500 mm/s²")
  double y = 0.0;
  Rgb colour{0.80, 0.10, 0.10};
  bool dashed = true;
};

struct Chart {
  std::string title;
  std::string x_title, y_title;  // with their units: "t [s]", "contour error [µm]"
  std::vector<Series> series;
  std::vector<Level> levels;
  std::optional<std::pair<double, double>> x_range, y_range;  // fixed ranges; fitted to the data when empty
  bool legend = true;
};

struct ChartPicture {
  int width = 1600, height = 900;
  // None by default: the lines are 1.5-3 px wide and mostly dense envelopes, where smoothing changes edge pixels
  // only, and 4x multisampling would cost ~0.2 s of CPU per picture on llvmpipe for that. FXAA also softens the text.
  Antialiasing antialiasing = Antialiasing::None;
  std::vector<std::string> caption;  // lines above the charts; the first one larger
  std::vector<Chart> charts;         // stacked top to bottom, each the same height
};

// Where a chart's plot area landed: its axis ranges and its corners in image pixels (from the top-left corner).
struct ChartFrame {
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  double left_px = 0, right_px = 0, top_px = 0, bottom_px = 0;
  Eigen::Vector2d pixel(double x, double y) const {
    return {left_px + (x - x_min) / (x_max - x_min) * (right_px - left_px),
            bottom_px - (y - y_min) / (y_max - y_min) * (bottom_px - top_px)};
  }
};

struct ChartImage {
  Image image;
  std::vector<ChartFrame> frames;  // one per chart, in order
};

// Colours for series k = 0, 1, ... (Tableau 10: distinct, and distinct from the red of limits for k < 3).
Rgb series_colour(int k);

// A series drawn in series_colour(colour).
inline Series make_series(std::string name, Eigen::ArrayXd x, Eigen::ArrayXd y, int colour, double width = 1.6,
                          bool dashed = false) {
  return Series{std::move(name), std::move(x), std::move(y), series_colour(colour), width, dashed};
}

// Throws core::Error for no charts, a chart without any finite point, series whose x and y differ in length, or an
// empty fixed range.
ChartImage render_charts(Window& window, const ChartPicture& picture);

}  // namespace vmsim::render
