// Charts: vtkChartXY items in a context scene drawn by a plain renderer of the headless window (no vtkContextView:
// it would make an X11 render window of its own, unused but pointless here).
#include "render/chart.hpp"

#include "core/error.hpp"
#include "render/decimate.hpp"
#include "render/detail.hpp"
#include "render/fxaa.hpp"

#include <vtkActor2D.h>
#include <vtkAxis.h>
#include <vtkCellArray.h>
#include <vtkChartXY.h>
#include <vtkContextActor.h>
#include <vtkContextScene.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPen.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper2D.h>
#include <vtkProperty2D.h>
#include <vtkPlot.h>
#include <vtkRect.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkTable.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::render {

Rgb series_colour(int k) {
  static constexpr unsigned char kTableau[10][3] = {{31, 119, 180}, {255, 127, 14},  {44, 160, 44},   {148, 103, 189},
                                                    {140, 86, 75},  {227, 119, 194}, {127, 127, 127}, {188, 189, 34},
                                                    {23, 190, 207}, {214, 39, 40}};
  const auto& c = kTableau[((k % 10) + 10) % 10];
  return {c[0] / 255.0, c[1] / 255.0, c[2] / 255.0};
}

namespace {

vtkSmartPointer<vtkTable> xy_table(const Eigen::ArrayXd& x, const Eigen::ArrayXd& y) {
  auto t = vtkSmartPointer<vtkTable>::New();
  vtkNew<vtkDoubleArray> xa, ya;
  xa->SetName("x");
  ya->SetName("y");
  xa->SetNumberOfValues(x.size());
  ya->SetNumberOfValues(y.size());
  for (Eigen::Index k = 0; k < x.size(); ++k) {
    // A point with a NaN coordinate is a "bad point" to vtkPlotLine: the line stops before it and resumes after.
    const bool ok = std::isfinite(x[k]) && std::isfinite(y[k]);
    xa->SetValue(k, ok ? x[k] : std::numeric_limits<double>::quiet_NaN());
    ya->SetValue(k, ok ? y[k] : std::numeric_limits<double>::quiet_NaN());
  }
  t->AddColumn(xa);
  t->AddColumn(ya);
  return t;
}

void style_axis(vtkAxis* a, const std::string& title, int font_px) {
  a->SetTitle(title);
  detail::set_font(a->GetTitleProperties(), font_px, 0.10, 0.10, 0.12, true);
  detail::set_font(a->GetLabelProperties(), static_cast<int>(font_px * 0.9), 0.15, 0.15, 0.18);
  a->GetGridPen()->SetColor(222, 222, 226, 255);
  a->GetPen()->SetColor(90, 90, 96, 255);
}

// Round ticks (1, 2 or 5 x 10^k apart) about every `spacing_px` pixels over [lo, hi], labelled with as many
// decimals as the step needs. VTK's own ticks on a fixed range crowd a tall axis (one every 20 px).
void set_ticks(vtkAxis* a, double lo, double hi, double length_px, double spacing_px) {
  const double want = std::clamp(length_px / spacing_px, 3.0, 14.0);
  const double raw = (hi - lo) / want;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  double step = 10 * p;
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) {
      step = m * p;
      break;
    }
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  vtkNew<vtkDoubleArray> pos;
  vtkNew<vtkStringArray> labels;
  for (double t = std::ceil(lo / step - 1e-9) * step; t <= hi + 1e-9 * step; t += step) {
    const double v = std::abs(t) < 1e-9 * step ? 0.0 : t;  // no "-0"
    pos->InsertNextValue(v);
    labels->InsertNextValue(fmt::format("{:.{}f}", v, decimals));
  }
  a->SetCustomTickPositions(pos, labels);
}

}  // namespace

ChartImage render_charts(Window& window, const ChartPicture& pic) {
  detail::check_size(pic.width, pic.height, "render_charts");
  if (pic.charts.empty()) throw core::Error("render_charts: no charts to draw");
  // Check the data and find each chart's x extent (the levels span it).
  std::vector<std::pair<double, double>> xext;
  for (const Chart& c : pic.charts) {
    double lo = std::numeric_limits<double>::max(), hi = -lo;
    bool any = false;
    for (const Series& s : c.series) {
      if (s.x.size() != s.y.size())
        throw core::Error(fmt::format("render_charts: series \"{}\" of \"{}\" has {} x and {} y values", s.name,
                                      c.title, s.x.size(), s.y.size()));
      for (Eigen::Index k = 0; k < s.x.size(); ++k)
        if (std::isfinite(s.x[k]) && std::isfinite(s.y[k]))
          lo = std::min(lo, s.x[k]), hi = std::max(hi, s.x[k]), any = true;
    }
    if (!any) throw core::Error("render_charts: chart \"" + c.title + "\" has no finite data point");
    if (c.x_range) lo = c.x_range->first, hi = c.x_range->second;
    if (!(hi > lo)) {
      if (c.x_range) throw core::Error("render_charts: chart \"" + c.title + "\" has an empty x range");
      lo -= 0.5, hi += 0.5;  // a single x: a unit-wide window around it
    }
    if (c.y_range && !(c.y_range->second > c.y_range->first))
      throw core::Error("render_charts: chart \"" + c.title + "\" has an empty y range");
    xext.emplace_back(lo, hi);
  }

  const int W = pic.width, H = pic.height;
  const double scale = std::min(W / 1600.0, H / 900.0);
  const int font = std::max(10, static_cast<int>(std::lround(20 * std::clamp(scale, 0.5, 2.5))));
  vtkRenderWindow* rw = detail::begin_picture(window, W, H);
  rw->SetNumberOfLayers(1);
  vtkNew<vtkRenderer> ren;
  ren->SetBackground(1, 1, 1);
  detail::set_antialiasing(rw, ren, pic.antialiasing);
  rw->AddRenderer(ren);
  vtkNew<vtkContextScene> scene;
  scene->SetRenderer(ren);
  vtkNew<vtkContextActor> actor;
  actor->SetScene(scene);
  ren->AddActor(actor);

  // Caption band, then the charts in equal bands.
  const int n_caption = static_cast<int>(pic.caption.size());
  const double big = font * 1.25, small = font * 0.95;
  const double top_band = n_caption > 0 ? 12 + big + (n_caption - 1) * small * 1.35 + 8 : 0;
  std::vector<vtkSmartPointer<vtkTextActor>> texts;
  double ty = H - 12 - big;
  for (int k = 0; k < n_caption; ++k) {
    auto t = vtkSmartPointer<vtkTextActor>::New();
    t->SetInput(pic.caption[static_cast<std::size_t>(k)].c_str());
    detail::set_font(t->GetTextProperty(), static_cast<int>(k == 0 ? big : small), 0.08, 0.08, 0.10, k == 0);
    t->SetDisplayPosition(14, static_cast<int>(ty));
    ren->AddActor2D(t);
    texts.push_back(t);
    ty -= k == 0 ? small * 1.45 : small * 1.35;
  }
  const int n = static_cast<int>(pic.charts.size());
  const double band = (H - top_band) / n;
  // Every chart's plot area at the same place across the bands (AXES_TO_RECT: the rectangle is the axes' box, the
  // labels, titles and legend go into these margins), so stacked charts line up in x.
  // The right margin fits the longest legend entry (line sample, gap, text at ~0.5 em per character).
  std::size_t longest = 0;
  auto glyphs = [](const std::string& t) {
    return static_cast<std::size_t>(std::count_if(t.begin(), t.end(), [](char ch) { return (ch & 0xC0) != 0x80; }));
  };
  for (const Chart& c : pic.charts) {
    if (!c.legend) continue;
    for (const Series& sr : c.series) longest = std::max(longest, glyphs(sr.name));
    for (const Level& l : c.levels) longest = std::max(longest, glyphs(l.name));
  }
  const double m_left = 5.5 * font;
  const double m_right =
      longest > 0 ? std::min(0.45 * W, 4.0 * font + 0.52 * font * static_cast<double>(longest)) : 1.5 * font;
  const double m_top = 2.0 * font, m_bottom = 3.3 * font;
  if (W - m_left - m_right < 32 || band - m_top - m_bottom < 16)
    throw core::Error(
        fmt::format("render_charts: {}x{} pixels are too small for {} stacked chart(s) with their "
                    "labels (at least {}x{})",
                    W, H, n, static_cast<int>(std::ceil(std::max<double>(W, m_left + m_right + 32))),
                    static_cast<int>(std::ceil(top_band + n * (m_top + m_bottom + 16)))));
  std::vector<vtkSmartPointer<vtkChartXY>> charts;
  std::vector<vtkSmartPointer<vtkTable>> tables;  // kept alive until the picture is drawn
  std::vector<vtkSmartPointer<vtkActor2D>> legend;
  for (int ci = 0; ci < n; ++ci) {
    const Chart& c = pic.charts[static_cast<std::size_t>(ci)];
    auto chart = vtkSmartPointer<vtkChartXY>::New();
    chart->SetLayoutStrategy(vtkChart::AXES_TO_RECT);
    const double bottom = H - top_band - (ci + 1) * band + m_bottom;
    chart->SetSize(vtkRectf(static_cast<float>(m_left), static_cast<float>(bottom),
                            static_cast<float>(W - m_left - m_right), static_cast<float>(band - m_top - m_bottom)));
    if (!c.title.empty()) {
      chart->SetTitle(c.title);
      detail::set_font(chart->GetTitleProperties(), static_cast<int>(font * 1.05), 0.08, 0.08, 0.10, true);
    }
    style_axis(chart->GetAxis(vtkAxis::BOTTOM), c.x_title, font);
    style_axis(chart->GetAxis(vtkAxis::LEFT), c.y_title, font);
    vtkAxis* xa = chart->GetAxis(vtkAxis::BOTTOM);
    xa->SetBehavior(vtkAxis::FIXED);
    xa->SetRange(xext[static_cast<std::size_t>(ci)].first, xext[static_cast<std::size_t>(ci)].second);
    // y: the given range, or the data's and the levels' with a margin, so that a limit line never sits on the
    // plot's border.
    double ylo = std::numeric_limits<double>::max(), yhi = -ylo;
    if (c.y_range) {
      ylo = c.y_range->first, yhi = c.y_range->second;
    } else {
      for (const Series& s : c.series)
        for (Eigen::Index k = 0; k < s.y.size(); ++k)
          if (std::isfinite(s.x[k]) && std::isfinite(s.y[k])) ylo = std::min(ylo, s.y[k]), yhi = std::max(yhi, s.y[k]);
      for (const Level& l : c.levels)
        if (std::isfinite(l.y)) ylo = std::min(ylo, l.y), yhi = std::max(yhi, l.y);
      const double span = yhi - ylo, pad = span > 0 ? 0.06 * span : std::max(1e-9, 0.5 * std::abs(yhi));
      ylo -= pad, yhi += pad;
    }
    chart->GetAxis(vtkAxis::LEFT)->SetBehavior(vtkAxis::FIXED);
    chart->GetAxis(vtkAxis::LEFT)->SetRange(ylo, yhi);
    set_ticks(chart->GetAxis(vtkAxis::LEFT), ylo, yhi, band - m_top - m_bottom, 2.6 * font);
    set_ticks(xa, xext[static_cast<std::size_t>(ci)].first, xext[static_cast<std::size_t>(ci)].second,
              W - m_left - m_right, 5.5 * font);
    const double lw = std::clamp(scale, 0.75, 3.0);  // thinner than 1.5 px, antialiased lines fade
    // Each series reduced to what the plot's pixel columns can show (render/decimate.hpp): the same pixels, a
    // fraction of the strokes (a 10 000-bin envelope is ~7 full-height strokes per column otherwise).
    const int columns = static_cast<int>(std::ceil(W - m_left - m_right));
    for (const Series& s : c.series) {
      const Polyline line = column_envelope(s.x, s.y, xext[static_cast<std::size_t>(ci)].first,
                                            xext[static_cast<std::size_t>(ci)].second, columns);
      auto t = xy_table(line.x, line.y);
      tables.push_back(t);
      vtkPlot* p = chart->AddPlot(vtkChart::LINE);
      p->SetInputData(t, 0, 1);
      p->SetColor(s.colour[0], s.colour[1], s.colour[2]);
      p->SetWidth(static_cast<float>(std::max(1.0, s.width * lw)));
      if (s.dashed) p->GetPen()->SetLineType(vtkPen::DASH_LINE);
      p->SetLabel(s.name);
    }
    for (const Level& l : c.levels) {
      Eigen::ArrayXd x(2), y(2);
      x << xext[static_cast<std::size_t>(ci)].first, xext[static_cast<std::size_t>(ci)].second;
      y << l.y, l.y;
      auto t = xy_table(x, y);
      tables.push_back(t);
      vtkPlot* p = chart->AddPlot(vtkChart::LINE);
      p->SetInputData(t, 0, 1);
      p->SetColor(l.colour[0], l.colour[1], l.colour[2]);
      p->SetWidth(static_cast<float>(std::max(1.0, 1.6 * lw)));
      if (l.dashed) p->GetPen()->SetLineType(vtkPen::DASH_LINE);
      p->SetLabel(l.name);
    }
    // The legend goes into the right margin, beside the plot, drawn here: VTK's own legend sits over the data
    // (inline) or, with the axes placed on a rectangle, still inside it.
    chart->SetShowLegend(false);
    if (c.legend) {
      double ly = H - top_band - ci * band - m_top - 0.2 * font;
      auto entry = [&](const std::string& name, const Rgb& colour, double width, bool dashed) {
        if (name.empty()) return;
        const double x0 = W - m_right + 0.8 * font, x1 = x0 + 2.2 * font, yl = ly - 0.35 * font;
        vtkNew<vtkPoints> p;
        vtkNew<vtkCellArray> lines;
        const int pieces = dashed ? 3 : 1;
        for (int k = 0; k < pieces; ++k) {
          const double a = x0 + (x1 - x0) * k / pieces, b = a + (x1 - x0) / pieces * (dashed ? 0.6 : 1.0);
          const vtkIdType ids[2] = {p->InsertNextPoint(a, yl, 0), p->InsertNextPoint(b, yl, 0)};
          lines->InsertNextCell(2, ids);
        }
        vtkNew<vtkPolyData> pd;
        pd->SetPoints(p);
        pd->SetLines(lines);
        vtkNew<vtkPolyDataMapper2D> m;
        m->SetInputData(pd);
        auto a = vtkSmartPointer<vtkActor2D>::New();
        a->SetMapper(m);
        a->GetProperty()->SetColor(colour[0], colour[1], colour[2]);
        a->GetProperty()->SetLineWidth(static_cast<float>(std::max(1.5, width * lw)));
        ren->AddActor2D(a);
        legend.push_back(a);
        auto t = vtkSmartPointer<vtkTextActor>::New();
        t->SetInput(name.c_str());
        detail::set_font(t->GetTextProperty(), static_cast<int>(font * 0.85), 0.08, 0.08, 0.10);
        t->SetDisplayPosition(static_cast<int>(x1 + 0.5 * font), static_cast<int>(ly - 0.8 * font));
        ren->AddActor2D(t);
        texts.push_back(t);
        ly -= 1.3 * font;
      };
      for (const Series& sr : c.series) entry(sr.name, sr.colour, sr.width, sr.dashed);
      for (const Level& l : c.levels) entry(l.name, l.colour, 1.6, l.dashed);
    }
    scene->AddItem(chart);
    charts.push_back(chart);
  }

  ChartImage out;
  out.image = detail::finish_picture(window);
  if (pic.antialiasing == Antialiasing::Fxaa) fxaa(out.image, PixelRect{0, 0, W, H});
  for (const auto& chart : charts) {
    ChartFrame f;
    vtkAxis* xa = chart->GetAxis(vtkAxis::BOTTOM);
    vtkAxis* ya = chart->GetAxis(vtkAxis::LEFT);
    f.x_min = xa->GetMinimum(), f.x_max = xa->GetMaximum();
    f.y_min = ya->GetMinimum(), f.y_max = ya->GetMaximum();
    // The plot area's corners in scene coordinates (pixels, y up from the bottom).
    const int* p1 = chart->GetPoint1();
    const int* p2 = chart->GetPoint2();
    f.left_px = p1[0], f.right_px = p2[0];
    f.bottom_px = H - p1[1], f.top_px = H - p2[1];
    out.frames.push_back(f);
  }
  return out;
}

}  // namespace vmsim::render
