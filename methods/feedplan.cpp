#include "methods/feedplan.hpp"
#include "core/timing.hpp"
#include "core/units.hpp"

#include "core/error.hpp"

#include <ClpSimplex.hpp>
#include <CoinPackedMatrix.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

namespace vmsim::methods {

namespace {

using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;
using core::units::kInf;
constexpr double kTiny = 1e-12;

using core::seconds_since;

// Sub-samples per interval for the interval maxima (curvature, |t_r|, |k_r|).
constexpr int kSub = 8;

void init_maxima(PathSamples& ps) {
  const Index n = ps.size();
  ps.kappa_max.resize(n);
  ps.t_abs_max.resize(n, 3);
  ps.k_abs_max.resize(n, 3);
  for (Index i = 0; i < n; ++i) {
    ps.kappa_max[i] = ps.k.row(i).norm();
    ps.t_abs_max.row(i) = ps.t.row(i).cwiseAbs();
    ps.k_abs_max.row(i) = ps.k.row(i).cwiseAbs();
  }
}

void update_maxima(PathSamples& ps, Index i, const Eigen::Vector3d& t, const Eigen::Vector3d& k) {
  ps.kappa_max[i] = std::max(ps.kappa_max[i], k.norm());
  ps.t_abs_max.row(i) = ps.t_abs_max.row(i).cwiseMax(t.cwiseAbs().transpose());
  ps.k_abs_max.row(i) = ps.k_abs_max.row(i).cwiseMax(k.cwiseAbs().transpose());
}

void resize_samples(PathSamples& ps, Index n) {
  ps.s.resize(n);
  ps.u.setConstant(n, std::numeric_limits<double>::quiet_NaN());
  ps.p.resize(n, 3);
  ps.t.resize(n, 3);
  ps.k.resize(n, 3);
  ps.dk.resize(n, 3);
}

Index sample_count(double length, double ds) {
  if (!(ds > 0) || !std::isfinite(ds))
    throw core::Error(fmt::format("feed plan: sample spacing {} mm (expected > 0)", ds));
  if (!(length > 0)) throw core::Error("feed plan: the path has no length");
  const double n = std::ceil(length / ds - 1e-9) + 1;
  if (n > 5e7) throw core::Error(fmt::format("feed plan: {:.0f} samples of {} mm: too many", n, ds));
  return std::max<Index>(3, static_cast<Index>(n));
}

// One constraint row a_i q_i + a_j q_j (+ a_k q_k) in [lo, hi].
struct Row {
  Index i[3];
  double c[3];
  int n;
  double lo, hi;
};

// Eq. 23 for interval [i, i+1] and axis r, at its first (end = 0) or second (end = 1) sample: the axis acceleration
// t_r (q_{i+1} - q_i) / (2 ds) + k_r q_end.
Row accel_row(const PathSamples& ps, Index i, int r, int end, double A) {
  const Index e = i + end;
  const double a = ps.t(e, r) / (2 * ps.ds), kr = ps.k(e, r);
  Row row{{i, i + 1, 0}, {-a + (end == 0 ? kr : 0.0), a + (end == 1 ? kr : 0.0), 0}, 2, -A, A};
  return row;
}

// The jerk model at interior sample i, axis r, divided by f: t_r q''/2 + 3/2 k_r q' + k'_r q (central differences).
Row jerk_row(const PathSamples& ps, Index i, int r) {
  const double h = ps.ds, t = ps.t(i, r), k = ps.k(i, r), dk = ps.dk(i, r);
  const double c2 = t / (2 * h * h), c1 = 1.5 * k / (2 * h);
  return Row{{i - 1, i, i + 1}, {c2 - c1, -2 * c2 + dk, c2 + c1}, 3, -kInf, kInf};
}

bool row_is_empty(const Row& r) {
  for (int j = 0; j < r.n; ++j)
    if (std::abs(r.c[j]) > kTiny) return false;
  return true;
}

// Backward acceleration envelope: env_i is the largest q_i from which some q_{i+1} <= env_{i+1} satisfies the
// interval's acceleration rows (the set of such q_i is an interval [0, env_i]: q = 0 satisfies every row), under
// q_i <= ub_i. Bisection on q_i; the rows give q_{i+1} an interval for each trial q_i.
std::vector<double> backward_envelope(const PathSamples& ps, const std::vector<double>& ub, const Eigen::Vector3d& A) {
  const Index n = ps.size();
  std::vector<double> env(static_cast<std::size_t>(n));
  env.back() = std::min(ub.back(), 0.0);
  std::vector<Row> rows;
  for (Index i = n - 2; i >= 0; --i) {
    rows.clear();
    for (int r = 0; r < 3; ++r) {
      if (!std::isfinite(A[r])) continue;
      for (int end = 0; end < 2; ++end) {
        Row row = accel_row(ps, i, r, end, A[r]);
        if (!row_is_empty(row)) rows.push_back(row);
      }
    }
    const double qn_max = env[static_cast<std::size_t>(i + 1)];
    auto feasible = [&](double qi) {
      double lo = 0.0, hi = qn_max;
      for (const Row& row : rows) {
        const double ci = row.c[0], cn = row.c[1];
        const double rlo = row.lo - ci * qi, rhi = row.hi - ci * qi;
        if (std::abs(cn) <= kTiny) {
          if (rlo > 0 || rhi < 0) return false;
          continue;
        }
        double a = rlo / cn, b = rhi / cn;
        if (cn < 0) std::swap(a, b);
        lo = std::max(lo, a), hi = std::min(hi, b);
      }
      return lo <= hi * (1 + 1e-12) + 1e-12;
    };
    const double cap = ub[static_cast<std::size_t>(i)];
    if (feasible(cap)) {
      env[static_cast<std::size_t>(i)] = cap;
      continue;
    }
    double lo = 0.0, hi = cap;
    for (int it = 0; it < 60 && hi - lo > 1e-12 * hi; ++it) {
      const double m = 0.5 * (lo + hi);
      (feasible(m) ? lo : hi) = m;
    }
    env[static_cast<std::size_t>(i)] = lo;
  }
  return env;
}

// Clp with the rows and columns of one window.
struct WindowLp {
  ClpSimplex lp;
  std::vector<std::pair<Index, int>> jerk;  // (sample, axis) of each jerk row, rows jerk_first ..
  int jerk_first = 0;
  Index a = 0, m = 0;  // first sample, columns
  Index nonzeros = 0;
};

// Dual simplex (then primal from its basis if round-off left it unproven); false when no optimum is proven.
bool try_solve(WindowLp& w, FeedPlanStats& st) {
  const auto t0 = Clock::now();
  w.lp.dual();
  st.lp_seconds += seconds_since(t0);
  ++st.lp_solves;
  if (!w.lp.isProvenOptimal()) {
    const auto t1 = Clock::now();
    w.lp.primal();
    st.lp_seconds += seconds_since(t1);
    ++st.lp_solves;
  }
  return w.lp.isProvenOptimal();
}

void solve(WindowLp& w, FeedPlanStats& st, Index window_first, const char* phase) {
  const auto t0 = Clock::now();
  w.lp.dual();
  st.lp_seconds += seconds_since(t0);
  ++st.lp_solves;
  if (!w.lp.isProvenOptimal()) {
    // Round-off after bound changes: a fresh primal solve from the current basis settles it, or proves infeasibility.
    const auto t1 = Clock::now();
    w.lp.primal();
    st.lp_seconds += seconds_since(t1);
    ++st.lp_solves;
  }
  if (!w.lp.isProvenOptimal())
    throw core::Error(
        fmt::format("feed plan: the linear program of the window starting at sample {} has no solution "
                    "({}; Clp status {}); try a longer window or overlap",
                    window_first, phase, w.lp.status()));
}

}  // namespace

// ---- sampling ----------------------------------------------------------------------------------------------------

PathSamples sample_nurbs(const motion::NurbsCurve& curve, double ds) {
  const motion::NurbsArcLength arc(curve);
  const Index n = sample_count(arc.length(), ds);
  PathSamples ps;
  ps.ds = arc.length() / static_cast<double>(n - 1);
  resize_samples(ps, n);
  for (Index i = 0; i < n; ++i) {
    const double s = i + 1 == n ? arc.length() : i * ps.ds;
    const double u = arc.u_at(s);
    const motion::ArcJet j = motion::arc_jet(motion::nurbs_derivs(curve, u));
    ps.s[i] = s;
    ps.u[i] = u;
    ps.p.row(i) = j.p.transpose();
    ps.t.row(i) = j.t.transpose();
    ps.k.row(i) = j.k.transpose();
    ps.dk.row(i) = j.dk.transpose();
  }
  init_maxima(ps);
  // Interval maxima: sub-samples evenly in u between neighbouring samples, each counted for the nearer sample.
  for (Index i = 0; i + 1 < n; ++i) {
    for (int m = 1; m < kSub; ++m) {
      const double u = ps.u[i] + (ps.u[i + 1] - ps.u[i]) * m / kSub;
      const motion::ArcJet j = motion::arc_jet(motion::nurbs_derivs(curve, u));
      if (2 * m <= kSub) update_maxima(ps, i, j.t, j.k);
      if (2 * m >= kSub) update_maxima(ps, i + 1, j.t, j.k);
    }
  }
  return ps;
}

PathSamples sample_path(const motion::SmoothPath& sp, double ds) {
  const Index n = sample_count(sp.length, ds);
  PathSamples ps;
  ps.ds = sp.length / static_cast<double>(n - 1);
  resize_samples(ps, n);
  auto check_xyz = [](const motion::PathJet& j) {
    if (j.t.tail<3>().norm() > 1e-9)
      throw core::Error("feed plan: the path moves a rotary axis; feed planning covers X Y Z paths");
  };
  std::size_t hint = 0;
  for (Index i = 0; i < n; ++i) {
    const double s = i + 1 == n ? sp.length : i * ps.ds;
    hint = sp.piece_at(s, hint);
    const motion::PathPiece& pc = sp.pieces[hint];
    const motion::PathJet j = pc.jet_s(std::clamp(s - pc.s_begin, 0.0, pc.length));
    check_xyz(j);
    ps.s[i] = s;
    ps.p.row(i) = j.p.head<3>().transpose();
    ps.t.row(i) = j.t.head<3>().transpose();
    ps.k.row(i) = j.k.head<3>().transpose();
    ps.dk.row(i) = j.dk.head<3>().transpose();
  }
  init_maxima(ps);
  // Interval maxima: every piece's own points (its ends, and on curved pieces at least 8 and 8 per sample spacing),
  // each counted for the sample whose interval holds it, so a blend shorter than the spacing is not missed.
  for (const motion::PathPiece& pc : sp.pieces) {
    const bool curved = pc.kind != motion::PathPiece::Kind::Line;
    const int m = curved ? std::max(8, static_cast<int>(std::ceil(pc.length / ps.ds * kSub))) : 1;
    const double span = pc.u_end - pc.u_begin;
    for (int q = 0; q <= m; ++q) {
      const double u = pc.u_begin + span * q / m;
      const double s = pc.s_begin + (q == 0 ? 0.0 : (q == m ? pc.length : pc.s_at(u)));
      const Index i = std::clamp<Index>(static_cast<Index>(std::llround(s / ps.ds)), 0, n - 1);
      const motion::PathJet j = pc.jet_at_u(u);
      check_xyz(j);
      update_maxima(ps, i, j.t.head<3>(), j.k.head<3>());
    }
  }
  return ps;
}

// ---- the plan ----------------------------------------------------------------------------------------------------

FeedPlan plan_feed(const PathSamples& ps, const FeedPlanOptions& opt) {
  const auto t_start = Clock::now();
  const FeedPlanLimits& L = opt.limits;
  if (!(L.period_s > 0) || !(L.max_feed_mm_per_s > 0) || !std::isfinite(L.max_feed_mm_per_s))
    throw core::Error("feed plan: the period T and the maximum feed must be > 0");
  for (int r = 0; r < 3; ++r)
    if (!(L.axis_velocity[r] > 0) || !(L.axis_acceleration[r] > 0) || !(L.axis_jerk[r] > 0))
      throw core::Error("feed plan: axis velocity, acceleration and jerk limits must be > 0 (infinity: none)");
  const bool contour = L.contour_error_mm > 0;
  if (contour && !opt.contour_model) throw core::Error("feed plan: a contour-error tolerance needs a servo model");
  const Index n = ps.size();
  if (n < 3) throw core::Error("feed plan: the path needs at least 3 samples");
  const bool jerk = L.axis_jerk.array().isFinite().any();
  if (opt.contour_scale.size() != 0 &&
      (opt.contour_scale.size() != n || !(opt.contour_scale > 0).all() || !(opt.contour_scale <= 1).all()))
    throw core::Error("feed plan: contour_scale needs one factor in (0, 1] per sample");

  FeedPlan plan;
  plan.s = ps.s;
  for (Eigen::ArrayXd* a : {&plan.f_star, &plan.bound_contour, &plan.bound_chord, &plan.bound_axis_velocity,
                            &plan.bound_centripetal, &plan.omega0})
    a->setConstant(n, kInf);

  // Eq. 24: the pointwise bound, the smallest over each sample's interval.
  std::vector<double> ub(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) {
    const double kap = ps.kappa_max[i];
    const double rho = kap > kTiny ? 1.0 / kap : kInf;
    double f = L.max_feed_mm_per_s;       // eq. 17
    if (contour && std::isfinite(rho)) {  // eq. 11-13
      const double eps = L.contour_error_mm * (opt.contour_scale.size() == n ? opt.contour_scale[i] : 1.0);
      plan.omega0[i] = opt.contour_model->omega0(eps * kap);
      plan.bound_contour[i] = plan.omega0[i] * rho;
    }
    if (L.chord_error_mm > 0 && std::isfinite(rho)) {  // eq. 15
      const double d = L.chord_error_mm;
      plan.bound_chord[i] =
          rho <= d ? 2 * rho / L.period_s : 2 * std::sqrt(rho * rho - (rho - d) * (rho - d)) / L.period_s;
    }
    for (int r = 0; r < 3; ++r) {
      if (ps.t_abs_max(i, r) > kTiny)  // eq. 22
        plan.bound_axis_velocity[i] = std::min(plan.bound_axis_velocity[i], L.axis_velocity[r] / ps.t_abs_max(i, r));
      if (ps.k_abs_max(i, r) > kTiny && std::isfinite(L.axis_acceleration[r]))  // eq. 23 with no tangential part
        plan.bound_centripetal[i] =
            std::min(plan.bound_centripetal[i], std::sqrt(L.axis_acceleration[r] / ps.k_abs_max(i, r)));
    }
    f = std::min(
        {f, plan.bound_contour[i], plan.bound_chord[i], plan.bound_axis_velocity[i], plan.bound_centripetal[i]});
    plan.f_star[i] = f;
    ub[static_cast<std::size_t>(i)] = f * f;
  }
  ub.front() = ub.back() = 0.0;  // rest at both ends
  const std::vector<double> env = backward_envelope(ps, ub, L.axis_acceleration);

  // Windows.
  int overlap = opt.overlap_samples;
  if (overlap <= 0) {
    const double a = L.axis_acceleration.minCoeff(), f = L.max_feed_mm_per_s;
    double brake = f * f / (2 * a);
    const double j = L.axis_jerk.minCoeff();
    if (std::isfinite(j)) brake += f * a / j;
    overlap = std::max(50, static_cast<int>(std::ceil(2 * brake / ps.ds)) + 10);
  }
  const Index window = std::max<Index>(opt.window_samples, 3 * static_cast<Index>(overlap));
  plan.stats.overlap_samples = overlap;
  plan.stats.window_samples = static_cast<int>(window);

  std::vector<double> q(static_cast<std::size_t>(n), 0.0);
  std::vector<double> prev_q(static_cast<std::size_t>(n), 0.0);  // the previous window's final solution
  Index prev_end = 0;                                            // .. on samples before this
  Index a = 0;
  std::vector<Row> rows;
  while (true) {
    const Index b = std::min(n, a + window);
    const bool last = b == n;
    const Index keep_end = last ? n : b - overlap;
    const Index m = b - a;
    // Columns: q_a .. q_{b-1}; the first window's q_0 and the path's last sample are 0, later windows start from the
    // two samples the previous window fixed.
    std::vector<double> clo(static_cast<std::size_t>(m), 0.0), chi(static_cast<std::size_t>(m)),
        obj(static_cast<std::size_t>(m), -1.0);
    std::vector<char> fixed(static_cast<std::size_t>(m), 0);
    for (Index i = a; i < b; ++i) chi[static_cast<std::size_t>(i - a)] = ub[static_cast<std::size_t>(i)];
    if (!last) chi.back() = std::min(chi.back(), env[static_cast<std::size_t>(b - 1)]);
    for (Index i = a; i < std::min(b, a + (a == 0 ? 1 : 2)); ++i) {
      const std::size_t j = static_cast<std::size_t>(i - a);
      clo[j] = chi[j] = q[static_cast<std::size_t>(i)];
      fixed[j] = 1;
      obj[j] = 0.0;
    }
    // Rows: acceleration at both ends of every interval (eq. 23), then jerk at every interior sample.
    rows.clear();
    auto all_fixed = [&](const Row& r) {
      for (int j = 0; j < r.n; ++j)
        if (!fixed[static_cast<std::size_t>(r.i[j] - a)]) return false;
      return true;
    };
    for (Index i = a; i + 1 < b; ++i)
      for (int r = 0; r < 3; ++r) {
        if (!std::isfinite(L.axis_acceleration[r])) continue;
        for (int end = 0; end < 2; ++end) {
          const Row row = accel_row(ps, i, r, end, L.axis_acceleration[r]);
          if (!row_is_empty(row) && !all_fixed(row)) rows.push_back(row);
        }
      }
    WindowLp w;
    w.a = a;
    w.m = m;
    w.jerk_first = static_cast<int>(rows.size());
    if (jerk) {
      for (Index i = a + 1; i + 1 < b; ++i)
        for (int r = 0; r < 3; ++r) {
          if (!std::isfinite(L.axis_jerk[r])) continue;
          const Row row = jerk_row(ps, i, r);
          if (row_is_empty(row) || all_fixed(row)) continue;
          rows.push_back(row);
          w.jerk.emplace_back(i, r);
        }
    }
    std::vector<int> ri, ci;
    std::vector<double> v, rlo, rhi;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const Row& r = rows[k];
      for (int j = 0; j < r.n; ++j) {
        if (r.c[j] == 0.0) continue;
        ri.push_back(static_cast<int>(k));
        ci.push_back(static_cast<int>(r.i[j] - a));
        v.push_back(r.c[j]);
      }
      rlo.push_back(std::isfinite(r.lo) ? r.lo : -COIN_DBL_MAX);
      rhi.push_back(std::isfinite(r.hi) ? r.hi : COIN_DBL_MAX);
    }
    const CoinPackedMatrix matrix(false, ri.data(), ci.data(), v.data(), static_cast<CoinBigIndex>(v.size()));
    w.lp.setLogLevel(0);
    w.lp.loadProblem(matrix, clo.data(), chi.data(), obj.data(), rlo.data(), rhi.data());
    w.nonzeros = static_cast<Index>(v.size());
    plan.stats.lp_columns_max = std::max(plan.stats.lp_columns_max, m);
    plan.stats.lp_rows_max = std::max<Index>(plan.stats.lp_rows_max, static_cast<Index>(rows.size()));
    plan.stats.lp_nonzeros_max = std::max(plan.stats.lp_nonzeros_max, w.nonzeros);

    // Acceleration-limited solution first (jerk rows free), then the jerk linearised about it, iterated.
    solve(w, plan.stats, a, "acceleration only");
    std::vector<double> qw(w.lp.primalColumnSolution(), w.lp.primalColumnSolution() + m);
    int iterations = 0;
    if (!w.jerk.empty()) {
      // Linearisation points: the acceleration-only solution, except where the previous window's final solution P
      // reaches: there sqrt(P), so that P (which keeps f |X| <= J) satisfies this window's linearised rows and the
      // fixed start can be continued (the acceleration-only q is higher, and its tighter J / f_bar may not be).
      std::vector<double> fbar(static_cast<std::size_t>(m));
      for (Index j = 0; j < m; ++j) {
        const std::size_t jj = static_cast<std::size_t>(j), gi = static_cast<std::size_t>(a + j);
        fbar[jj] = std::sqrt(std::max(0.0, a + j < prev_end ? std::min(prev_q[gi], qw[jj]) : qw[jj]));
      }
      auto set_jerk_bounds = [&]() {
        for (std::size_t k = 0; k < w.jerk.size(); ++k) {
          const auto [i, r] = w.jerk[k];
          const double f = fbar[static_cast<std::size_t>(i - a)];
          const double bnd = f > 1e-9 ? L.axis_jerk[r] / f : COIN_DBL_MAX;
          w.lp.setRowBounds(w.jerk_first + static_cast<int>(k), -bnd, bnd);
        }
      };
      std::vector<double> fbar_ok;
      for (iterations = 1; iterations <= opt.max_jerk_iterations; ++iterations) {
        set_jerk_bounds();
        if (iterations > 1) {
          // A later linearisation that has no solution (f_bar rose near the fixed start): keep the last iterate.
          if (!try_solve(w, plan.stats)) {
            fbar = fbar_ok;
            break;
          }
        } else {
          solve(w, plan.stats, a, "jerk linearised");
        }
        fbar_ok = fbar;
        const double* sol = w.lp.primalColumnSolution();
        double change = 0.0, qmax = 0.0;
        for (Index j = 0; j < m; ++j) {
          const std::size_t jj = static_cast<std::size_t>(j);
          change = std::max(change, std::abs(sol[j] - qw[jj]));
          qmax = std::max(qmax, qw[jj]);
          qw[jj] = sol[j];
          // Damped update of the linearisation point: in a jerk-bound stretch q ~ 1 / f_bar, for which
          // f_bar <- sqrt(q)^(2/3) f_bar^(1/3) is the fixed point in one step.
          const double fq = std::sqrt(std::max(0.0, sol[j]));
          fbar[jj] = fbar[jj] > 1e-9 ? std::pow(fq, 2.0 / 3.0) * std::cbrt(fbar[jj]) : fq;
        }
        if (change <= opt.jerk_tolerance * std::max(qmax, 1e-300)) break;
      }
      iterations = std::min(iterations, opt.max_jerk_iterations);
      // Safe final solve: q <= f_bar^2 with the jerk linearised at f_bar, so f |X| <= f_bar |X| <= J exactly. First
      // f_bar = sqrt of the last iterate (feasible when the iterations converged); else f_bar = the last iterate's
      // own linearisation point, which that iterate satisfies.
      const std::vector<double> q_last = qw;
      for (Index j = 0; j < m; ++j) {
        const std::size_t jj = static_cast<std::size_t>(j);
        fbar[jj] = std::sqrt(std::max(0.0, q_last[jj]));
        if (!fixed[jj]) w.lp.setColumnUpper(static_cast<int>(j), std::min(chi[jj], q_last[jj]));
      }
      set_jerk_bounds();
      if (!try_solve(w, plan.stats)) {
        fbar = fbar_ok;
        for (Index j = 0; j < m; ++j) {
          const std::size_t jj = static_cast<std::size_t>(j);
          if (!fixed[jj]) w.lp.setColumnUpper(static_cast<int>(j), std::min(chi[jj], fbar[jj] * fbar[jj]));
        }
        set_jerk_bounds();
        solve(w, plan.stats, a, "final jerk solve");
      }
      const double* sol = w.lp.primalColumnSolution();
      for (Index j = 0; j < m; ++j) qw[static_cast<std::size_t>(j)] = sol[j];
    }
    plan.stats.jerk_iterations_max = std::max(plan.stats.jerk_iterations_max, iterations);
    ++plan.stats.windows;
    for (Index i = a; i < b; ++i)
      prev_q[static_cast<std::size_t>(i)] = std::max(0.0, qw[static_cast<std::size_t>(i - a)]);
    prev_end = b;
    for (Index i = a; i < keep_end; ++i)
      if (!fixed[static_cast<std::size_t>(i - a)])
        q[static_cast<std::size_t>(i)] =
            std::clamp(qw[static_cast<std::size_t>(i - a)], 0.0, ub[static_cast<std::size_t>(i)]);
    if (last) break;
    a = keep_end - 2;
  }

  plan.feed.resize(n);
  for (Index i = 0; i < n; ++i) plan.feed[i] = std::sqrt(std::max(0.0, q[static_cast<std::size_t>(i)]));
  plan.time_s = 0.0;
  for (Index i = 0; i + 1 < n; ++i) {
    const double vs = plan.feed[i] + plan.feed[i + 1];
    plan.time_s += vs > 0 ? 2 * (ps.s[i + 1] - ps.s[i]) / vs : kInf;
  }
  plan.stats.total_seconds = seconds_since(t_start);
  return plan;
}

// ---- independent check -------------------------------------------------------------------------------------------

double FeedPlanCheck::worst() const {
  return std::max({feed, chord, contour, axis_velocity, axis_acceleration, axis_jerk});
}

FeedPlanCheck check_feed_plan(const PathSamples& ps, const Eigen::ArrayXd& f, const FeedPlanLimits& L,
                              const ContourErrorModel* model) {
  const Index n = ps.size();
  if (f.size() != n) throw core::Error("feed plan check: one feed per sample expected");
  FeedPlanCheck c;
  auto track = [](double v, Index i, double& worst, Index& at) {
    if (v > worst) worst = v, at = i;
  };
  for (Index i = 0; i < n; ++i) {
    track(f[i] / L.max_feed_mm_per_s, i, c.feed, c.feed_at);
    const double kap = ps.kappa_max[i];
    if (kap > kTiny) {
      const double rho = 1.0 / kap;
      if (L.chord_error_mm > 0) {  // eq. 14
        const double h = f[i] * L.period_s / 2;
        const double delta = h >= rho ? rho : rho - std::sqrt(rho * rho - h * h);
        track(delta / L.chord_error_mm, i, c.chord, c.chord_at);
      }
      if (L.contour_error_mm > 0 && model)  // eq. 7
        track(rho * model->error_ratio(f[i] / rho) / L.contour_error_mm, i, c.contour, c.contour_at);
    }
    for (int r = 0; r < 3; ++r) {
      track(ps.t_abs_max(i, r) * f[i] / L.axis_velocity[r], i, c.axis_velocity, c.velocity_at);  // eq. 22
      if (i + 1 < n && std::isfinite(L.axis_acceleration[r])) {  // eq. 23 at both ends of [i, i+1]
        const double at = (f[i + 1] * f[i + 1] - f[i] * f[i]) / (2 * (ps.s[i + 1] - ps.s[i]));
        for (Index e : {i, i + 1})
          track(std::abs(ps.t(e, r) * at + ps.k(e, r) * f[e] * f[e]) / L.axis_acceleration[r], i, c.axis_acceleration,
                c.acceleration_at);
      }
      if (i > 0 && i + 1 < n && std::isfinite(L.axis_jerk[r])) {  // f (t q''/2 + 3/2 k q' + k' q)
        const double h = ps.ds;
        const double q0 = f[i - 1] * f[i - 1], q1 = f[i] * f[i], q2 = f[i + 1] * f[i + 1];
        const double x =
            ps.t(i, r) * (q2 - 2 * q1 + q0) / (2 * h * h) + 1.5 * ps.k(i, r) * (q2 - q0) / (2 * h) + ps.dk(i, r) * q1;
        track(std::abs(f[i] * x) / L.axis_jerk[r], i, c.axis_jerk, c.jerk_at);
      }
    }
  }
  return c;
}

motion::FeedCeiling feed_ceiling(const FeedPlan& plan, const std::function<double(double)>& to_path_s) {
  motion::FeedCeiling c;
  const Index n = plan.feed.size();
  for (Index i = 0; i < n; ++i) {
    double f = plan.feed[i];
    if (!(f > 0)) f = i == 0 ? plan.feed[std::min<Index>(1, n - 1)] : plan.feed[std::max<Index>(0, n - 2)];
    if (!(f > 0)) continue;
    const double s = to_path_s ? to_path_s(plan.s[i]) : plan.s[i];
    if (!c.s_mm.empty() && !(s > c.s_mm.back())) continue;
    c.s_mm.push_back(s);
    c.feed_mm_per_s.push_back(f);
  }
  return c;
}

motion::FeedCeiling feed_profile(const FeedPlan& plan, double path_length_mm,
                                 const std::function<double(double)>& to_path_s) {
  motion::FeedCeiling c;
  c.follow = true;
  const Index n = plan.feed.size();
  if (n < 3) throw core::Error("feed profile: the plan needs at least 3 samples");
  for (Index i = 0; i < n; ++i) {
    const double s = i == 0 ? 0.0 : (i + 1 == n ? path_length_mm : (to_path_s ? to_path_s(plan.s[i]) : plan.s[i]));
    if (i + 1 < n && !(s < path_length_mm)) continue;  // the map's round-off at the end: the end point is kept
    if (!c.s_mm.empty() && !(s > c.s_mm.back())) continue;
    c.s_mm.push_back(s);
    c.feed_mm_per_s.push_back(i == 0 || i + 1 == n ? 0.0 : plan.feed[i]);
  }
  return c;
}

}  // namespace vmsim::methods
