#include "metrology/form.hpp"

#include "core/error.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <cmath>
#include <vector>

namespace vmsim::metrology {

namespace {

// P_0..P_n at t (Bonnet's recurrence).
void legendre(double t, int n, double* p) {
  p[0] = 1.0;
  if (n >= 1) p[1] = t;
  for (int k = 2; k <= n; ++k) p[k] = ((2.0 * k - 1.0) * t * p[k - 1] - (k - 1.0) * p[k - 2]) / k;
}

// Term index of P_a(u) P_b(v), a + b <= n, in the order (0,0), (1,0), (0,1), (2,0), (1,1), (0,2), ...
std::vector<std::pair<int, int>> terms(int n) {
  std::vector<std::pair<int, int>> t;
  for (int d = 0; d <= n; ++d)
    for (int b = 0; b <= d; ++b) t.emplace_back(d - b, b);
  return t;
}

}  // namespace

double FormFit::evaluate(double x, double y) const {
  std::vector<double> pu(static_cast<std::size_t>(degree + 1)), pv(static_cast<std::size_t>(degree + 1));
  legendre((x - x_centre_mm) / x_half_mm, degree, pu.data());
  legendre((y - y_centre_mm) / y_half_mm, degree, pv.data());
  const auto t = terms(degree);
  double z = 0;
  for (std::size_t k = 0; k < t.size(); ++k)
    z += coefficients[static_cast<Eigen::Index>(k)] * pu[static_cast<std::size_t>(t[k].first)] *
         pv[static_cast<std::size_t>(t[k].second)];
  return z;
}

FormFit fit_form(const core::HeightGrid& g, int degree,
                 const Eigen::Array<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>* use) {
  if (degree < 1 || degree > 10) throw core::Error(fmt::format("form removal: degree {} (1 to 10 expected)", degree));
  if (use && (use->rows() != g.ny() || use->cols() != g.nx()))
    throw core::Error("form removal: mask and grid differ in size");
  const Eigen::Index nx = g.nx(), ny = g.ny();
  FormFit f;
  f.degree = degree;
  f.x_centre_mm = g.x0_mm + 0.5 * static_cast<double>(nx - 1) * g.dx_mm;
  f.y_centre_mm = g.y0_mm + 0.5 * static_cast<double>(ny - 1) * g.dy_mm;
  f.x_half_mm = std::max(0.5 * static_cast<double>(nx - 1) * g.dx_mm, g.dx_mm);
  f.y_half_mm = std::max(0.5 * static_cast<double>(ny - 1) * g.dy_mm, g.dy_mm);
  const int n1 = degree + 1;
  const auto t = terms(degree);
  const int m = static_cast<int>(t.size());
  // P_a(u_i) for every column.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> pu(nx, n1);  // rows contiguous
  for (Eigen::Index i = 0; i < nx; ++i) legendre((g.x(i) - f.x_centre_mm) / f.x_half_mm, degree, pu.row(i).data());
  // Per row: S[a][a'] = sum_i P_a P_a', T[a] = sum_i z P_a, over the row's used points. Rows in parallel into
  // their own slots, summed in row order afterwards, so the result does not depend on the thread count.
  std::vector<Eigen::MatrixXd> rowS(static_cast<std::size_t>(ny));
  std::vector<Eigen::VectorXd> rowT(static_cast<std::size_t>(ny));
  std::vector<std::size_t> rowN(static_cast<std::size_t>(ny), 0);
#pragma omp parallel for schedule(dynamic, 16)
  for (Eigen::Index j = 0; j < ny; ++j) {
    Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n1, n1);
    Eigen::VectorXd T = Eigen::VectorXd::Zero(n1);
    std::size_t cnt = 0;
    for (Eigen::Index i = 0; i < nx; ++i) {
      const double z = g.z_mm(j, i);
      if (!std::isfinite(z) || (use && !(*use)(j, i))) continue;
      const auto p = pu.row(i);
      S.noalias() += p.transpose() * p;
      T.noalias() += z * p.transpose();
      ++cnt;
    }
    rowS[static_cast<std::size_t>(j)] = std::move(S);
    rowT[static_cast<std::size_t>(j)] = std::move(T);
    rowN[static_cast<std::size_t>(j)] = cnt;
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  std::vector<double> pv(static_cast<std::size_t>(n1));
  for (Eigen::Index j = 0; j < ny; ++j) {
    if (rowN[static_cast<std::size_t>(j)] == 0) continue;
    f.points += rowN[static_cast<std::size_t>(j)];
    legendre((g.y(j) - f.y_centre_mm) / f.y_half_mm, degree, pv.data());
    const Eigen::MatrixXd& S = rowS[static_cast<std::size_t>(j)];
    const Eigen::VectorXd& T = rowT[static_cast<std::size_t>(j)];
    for (int r = 0; r < m; ++r) {
      const auto [ar, br] = t[static_cast<std::size_t>(r)];
      b[r] += pv[static_cast<std::size_t>(br)] * T[ar];
      for (int c = 0; c < m; ++c) {
        const auto [ac, bc] = t[static_cast<std::size_t>(c)];
        A(r, c) += pv[static_cast<std::size_t>(br)] * pv[static_cast<std::size_t>(bc)] * S(ar, ac);
      }
    }
  }
  if (f.points < static_cast<std::size_t>(m))
    throw core::Error(
        fmt::format("form removal: {} valid points, a degree-{} form needs at least {}", f.points, degree, m));
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < m)
    throw core::Error(fmt::format("form removal: the valid points do not determine a degree-{} form (rank {} of {})",
                                  degree, qr.rank(), m));
  f.coefficients = qr.solve(b);
  // Plane part in plain units: P1(u) = u = (x - xc)/hx.
  f.z_centre_mm = f.evaluate(f.x_centre_mm, f.y_centre_mm);
  f.slope_x = f.coefficients[1] / f.x_half_mm;
  f.slope_y = f.coefficients[2] / f.y_half_mm;
  return f;
}

core::HeightGrid remove_form(const core::HeightGrid& g, int degree, FormFit* fit,
                             const Eigen::Array<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>* use) {
  FormFit f = fit_form(g, degree, use);
  core::HeightGrid out = g;
  const Eigen::Index nx = g.nx(), ny = g.ny();
  const auto t = terms(degree);
  const int n1 = degree + 1;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> pu(nx, n1);  // rows contiguous
  for (Eigen::Index i = 0; i < nx; ++i) legendre((g.x(i) - f.x_centre_mm) / f.x_half_mm, degree, pu.row(i).data());
  std::vector<double> rss(static_cast<std::size_t>(ny), 0.0);
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    std::vector<double> pv(static_cast<std::size_t>(n1));
    legendre((g.y(j) - f.y_centre_mm) / f.y_half_mm, degree, pv.data());
    // Row polynomial in u: q_a = sum_b c_ab P_b(v_j).
    std::vector<double> q(static_cast<std::size_t>(n1), 0.0);
    for (std::size_t k = 0; k < t.size(); ++k)
      q[static_cast<std::size_t>(t[k].first)] +=
          f.coefficients[static_cast<Eigen::Index>(k)] * pv[static_cast<std::size_t>(t[k].second)];
    double s = 0;
    for (Eigen::Index i = 0; i < nx; ++i) {
      double form = 0;
      for (int a = 0; a < n1; ++a) form += q[static_cast<std::size_t>(a)] * pu(i, a);
      double& z = out.z_mm(j, i);
      if (!std::isfinite(z)) continue;
      z -= form;
      if (!use || (*use)(j, i)) s += z * z;
    }
    rss[static_cast<std::size_t>(j)] = s;
  }
  double total = 0;
  for (double s : rss) total += s;
  f.rms_residual_mm = std::sqrt(total / static_cast<double>(f.points));
  if (fit) *fit = f;
  return out;
}

}  // namespace vmsim::metrology
