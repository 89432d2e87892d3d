// Iso-lines of a grid by marching squares (render/isolines.hpp). References: analytic level sets (circles of
// x^2 + y^2, on which every point must lie to the interpolation error of a grid edge, and closed loops of length
// 2 pi r), a linear height whose value at every point is known exactly, and VTK's vtkContourFilter on the same grid
// cut into two triangles per cell (what the pictures drew before): the same lines to within a cell.
#include "render/isolines.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <vtkCellArray.h>
#include <vtkContourFilter.h>
#include <vtkFloatArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>

#include <cmath>
#include <limits>
#include <map>
#include <vector>

using namespace vmsim;
using namespace vmsim::render;

namespace {

struct IsoTestGrid {
  std::vector<double> x, y;
  std::vector<float> v, z;
  Eigen::Index nx() const { return static_cast<Eigen::Index>(x.size()); }
};

// Nodes over [-1, 1]^2 at step h, the last step in x shorter (as a strided picture grid's last node), values
// x^2 + y^2, heights 3x + 2y + 1.
IsoTestGrid iso_test_grid(double h) {
  IsoTestGrid g;
  for (double t = -1; t < 1 - 1e-9; t += h) g.x.push_back(t), g.y.push_back(t);
  g.x.push_back(1.0), g.y.push_back(1.0);
  g.x[g.x.size() - 2] = 1.0 - 0.4 * h;  // an uneven last step in x
  for (double yy : g.y)
    for (double xx : g.x) {
      g.v.push_back(static_cast<float>(xx * xx + yy * yy));
      g.z.push_back(static_cast<float>(3 * xx + 2 * yy + 1));
    }
  return g;
}

double iso_seg_length(const IsoLines& l) {
  double s = 0;
  for (const auto& seg : l.segments) s += (l.points_mm.row(seg[0]) - l.points_mm.row(seg[1])).head<2>().norm();
  return s;
}

// Distance from p to the nearest segment of l (in x, y).
double iso_distance_to(const IsoLines& l, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::max();
  for (const auto& seg : l.segments) {
    const Eigen::Vector2d a = l.points_mm.row(seg[0]).head<2>().transpose(),
                          b = l.points_mm.row(seg[1]).head<2>().transpose();
    const double t = std::clamp((p - a).dot(b - a) / std::max((b - a).squaredNorm(), 1e-300), 0.0, 1.0);
    best = std::min(best, (a + t * (b - a) - p).norm());
  }
  return best;
}

}  // namespace

TEST(GridIsolines, CirclesOfTheAnalyticFieldAreClosedAndOnTheirRadius) {
  const double h = 0.02;
  const IsoTestGrid g = iso_test_grid(h);
  const std::vector<double> levels{0.25, 0.5};
  const IsoLines l = grid_isolines(g.x, g.y, g.v, g.z, levels);
  ASSERT_GT(l.points_mm.rows(), 100);
  // On a grid edge, linear interpolation of r^2 puts a point within h^2 / (8 r) of the circle (the chord's sag);
  // float storage of the values adds ~1e-7.
  for (Eigen::Index k = 0; k < l.points_mm.rows(); ++k) {
    const double r = l.points_mm.row(k).head<2>().norm();
    EXPECT_TRUE(std::abs(r - 0.5) < h * h / 4 + 1e-6 || std::abs(r - std::sqrt(0.5)) < h * h / 4 + 1e-6) << r;
    // Every point lies on a grid edge: its x is a node's, or its y is.
    const double px = l.points_mm(k, 0), py = l.points_mm(k, 1);
    const bool on_column = std::any_of(g.x.begin(), g.x.end(), [&](double c) { return std::abs(c - px) < 1e-6; });
    const bool on_row = std::any_of(g.y.begin(), g.y.end(), [&](double c) { return std::abs(c - py) < 1e-6; });
    EXPECT_TRUE(on_column || on_row) << px << " " << py;
    // z interpolated along that edge: the linear height exactly (to float storage).
    EXPECT_NEAR(l.points_mm(k, 2), 3 * px + 2 * py + 1, 2e-5);
  }
  // Closed loops: every point ends exactly two segments.
  std::map<std::int32_t, int> uses;
  for (const auto& s : l.segments) ++uses[s[0]], ++uses[s[1]];
  for (const auto& [p, n] : uses) EXPECT_EQ(n, 2) << "point " << p;
  // Length: the two circles' circumferences (inscribed polygons: a little shorter).
  const double want = 2 * M_PI * (0.5 + std::sqrt(0.5));
  EXPECT_NEAR(iso_seg_length(l), want, 2e-3 * want);
}

TEST(GridIsolines, AgreeWithVtkContourFilterOnTheTriangulatedGrid) {
  // A field with saddles and varied directions, where a cell's two triangles and its marching square differ most.
  const double h = 0.05;
  IsoTestGrid g = iso_test_grid(h);
  for (std::size_t j = 0; j < g.y.size(); ++j)
    for (std::size_t i = 0; i < g.x.size(); ++i)
      g.v[j * g.x.size() + i] = static_cast<float>(std::sin(3 * g.x[i]) * std::cos(2 * g.y[j]) + 0.3 * g.x[i]);
  const std::vector<double> levels{-0.5, 0.0, 0.2, 0.6};
  const IsoLines fe = grid_isolines(g.x, g.y, g.v, g.z, levels);

  // The reference: vtkContourFilter on two triangles per cell (a, b, c) and (a, c, d), as render/scene.cpp drew them.
  const auto nx = static_cast<vtkIdType>(g.x.size()), ny = static_cast<vtkIdType>(g.y.size());
  vtkNew<vtkPoints> pts;
  vtkNew<vtkFloatArray> sc;
  for (vtkIdType j = 0; j < ny; ++j)
    for (vtkIdType i = 0; i < nx; ++i) {
      pts->InsertNextPoint(g.x[i], g.y[j], g.z[j * nx + i]);
      sc->InsertNextValue(g.v[j * nx + i]);
    }
  vtkNew<vtkCellArray> tris;
  for (vtkIdType j = 0; j + 1 < ny; ++j)
    for (vtkIdType i = 0; i + 1 < nx; ++i) {
      const vtkIdType a = j * nx + i, b = a + 1, c = a + nx + 1, d = a + nx;
      const vtkIdType t1[3] = {a, b, c}, t2[3] = {a, c, d};
      tris->InsertNextCell(3, t1);
      tris->InsertNextCell(3, t2);
    }
  vtkNew<vtkPolyData> pd;
  pd->SetPoints(pts);
  pd->SetPolys(tris);
  pd->GetPointData()->SetScalars(sc);
  vtkNew<vtkContourFilter> cf;
  cf->SetInputData(pd);
  for (std::size_t k = 0; k < levels.size(); ++k) cf->SetValue(static_cast<int>(k), levels[k]);
  cf->Update();
  IsoLines ref;
  vtkPolyData* out = cf->GetOutput();
  ref.points_mm.resize(out->GetNumberOfPoints(), 3);
  for (vtkIdType p = 0; p < out->GetNumberOfPoints(); ++p) {
    double q[3];
    out->GetPoint(p, q);
    ref.points_mm.row(p) << q[0], q[1], q[2];
  }
  vtkIdType n = 0;
  const vtkIdType* ids = nullptr;
  for (out->GetLines()->InitTraversal(); out->GetLines()->GetNextCell(n, ids);)
    for (vtkIdType k = 0; k + 1 < n; ++k)
      ref.segments.push_back({static_cast<std::int32_t>(ids[k]), static_cast<std::int32_t>(ids[k + 1])});
  ASSERT_GT(ref.segments.size(), 50u);

  // Both ways: every point of one within a cell's half diagonal of the other's lines (they share the crossings on the
  // grid edges; inside a cell a line may go straight or bend at the diagonal).
  double worst = 0;
  for (Eigen::Index k = 0; k < fe.points_mm.rows(); ++k)
    worst = std::max(worst, iso_distance_to(ref, fe.points_mm.row(k).head<2>().transpose()));
  for (Eigen::Index k = 0; k < ref.points_mm.rows(); ++k)
    worst = std::max(worst, iso_distance_to(fe, ref.points_mm.row(k).head<2>().transpose()));
  EXPECT_LT(worst, h * std::sqrt(2.0) / 2) << "largest distance between the two sets of lines";
  // The triangles add the crossings on the cells' diagonals: a little longer lines, never shorter.
  EXPECT_NEAR(iso_seg_length(fe), iso_seg_length(ref), 0.03 * iso_seg_length(ref));
}

TEST(GridIsolines, NodesWithoutValueTakeNoPart) {
  const double h = 0.02;
  IsoTestGrid g = iso_test_grid(h);
  // A hole: no value within 0.2 of (0.6, 0).
  for (std::size_t j = 0; j < g.y.size(); ++j)
    for (std::size_t i = 0; i < g.x.size(); ++i)
      if (std::hypot(g.x[i] - 0.6, g.y[j]) < 0.2) g.v[j * g.x.size() + i] = std::numeric_limits<float>::quiet_NaN();
  const std::vector<double> levels{0.36};  // the circle r = 0.6 runs through the hole
  const IsoLines l = grid_isolines(g.x, g.y, g.v, g.z, levels);
  ASSERT_GT(l.segments.size(), 100u);
  for (Eigen::Index k = 0; k < l.points_mm.rows(); ++k) {
    ASSERT_TRUE(l.points_mm.row(k).allFinite());
    // No point on an edge that touches a hole node: at least a cell's diagonal from the hole's edge (0.2).
    EXPECT_GT(std::hypot(l.points_mm(k, 0) - 0.6, l.points_mm(k, 1)), 0.2 - 1.5 * h);
    EXPECT_NEAR(l.points_mm.row(k).head<2>().norm(), 0.6, h * h / 4 + 1e-6);
  }
  // The circle is open at the hole: its length is the circumference less the part inside the hole.
  EXPECT_LT(iso_seg_length(l), 2 * M_PI * 0.6 * 0.95);
  EXPECT_GT(iso_seg_length(l), 2 * M_PI * 0.6 * 0.80);
}

TEST(GridIsolines, RefusesMismatchedInput) {
  const IsoTestGrid g = iso_test_grid(0.5);
  const std::vector<double> levels{0.5};
  std::vector<float> short_v(g.v.begin(), g.v.end() - 1);
  EXPECT_THROW(grid_isolines(g.x, g.y, short_v, g.z, levels), core::Error);
  std::vector<double> desc(g.x.rbegin(), g.x.rend());
  EXPECT_THROW(grid_isolines(desc, g.y, g.v, g.z, levels), core::Error);
  const std::vector<double> one{0.0};
  const std::vector<float> v1(g.y.size()), z1(g.y.size());
  EXPECT_THROW(grid_isolines(one, g.y, v1, z1, levels), core::Error);
  EXPECT_TRUE(grid_isolines(g.x, g.y, g.v, g.z, {}).segments.empty());
}
