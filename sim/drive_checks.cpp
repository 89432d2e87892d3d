#include "sim/drive_checks.hpp"

#include "core/error.hpp"
#include "drives/drive_checks.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vmsim::sim {

namespace {

bool moves(const core::Setpoints& sp, Eigen::Index a) {
  return a < sp.position.cols() && (sp.position.col(a).array() != sp.position(0, a)).any();
}

const char* unit(const core::MachineAxis& ax) { return ax.kind == core::AxisKind::Rotary ? "rad" : "mm"; }

// The lowest finite value of a schedule column (NaN keeps the drive's own value); `own` when none is lower.
double lowest(const Eigen::MatrixXd& m, Eigen::Index a, double own) {
  double lo = own;
  if (a < m.cols())
    for (Eigen::Index k = 0; k < m.rows(); ++k)
      if (std::isfinite(m(k, a))) lo = std::min(lo, m(k, a));
  return lo;
}

}  // namespace

DriveChecks check_drives_before(const core::Machine& machine, const core::Setpoints& sp,
                                const std::vector<bool>& cascade) {
  DriveChecks out;
  for (std::size_t i = 0; i < machine.axes.size(); ++i) {
    const core::MachineAxis& ax = machine.axes[i];
    if (!ax.drive || i >= cascade.size() || !cascade[i] || !moves(sp, static_cast<Eigen::Index>(i))) continue;
    const drives::DriveStability d = drives::drive_stability(*ax.drive, sp.period_s);
    out.axes[ax.name] = {
        {"kv_te", d.kv_te},
        {"pole_radius", d.pole_radius},
        {"inner_pole_radius", d.inner_pole_radius},
        {"gain_margin", std::isfinite(d.gain_margin) ? nlohmann::json(d.gain_margin) : nlohmann::json("inf")},
        {"min_damping", d.min_damping}};
    for (core::Warning& w : drives::check_drive(*ax.drive, sp.period_s, ax.name, machine.source_file)) {
      if (w.severity == core::Warning::Severity::Invalid) throw core::Error(w.message);
      out.warnings.push_back(std::move(w));
    }
  }
  return out;
}

// The differences are never -0 (|.| clears the sign), so their maximum is the same in any order when none is NaN:
// two rows per instruction then (issue 21: a pass over every setpoint of every axis); with a NaN, in order.
void largest_setpoint_differences(const double* px, Eigen::Index n, double& d1_max, double& d2_max) {
  d1_max = 0, d2_max = 0;
  if (n >= 2) d1_max = std::max(d1_max, std::abs(px[1] - px[0]));
  Eigen::Index k = 2;
  bool ordered = true;
#if defined(__SSE2__)
  {
    const __m128d sign = _mm_set1_pd(-0.0), two = _mm_set1_pd(2.0);
    __m128d m1 = _mm_setzero_pd(), m2 = m1, nan = m1;
    for (; k + 2 <= n; k += 2) {
      const __m128d x0 = _mm_loadu_pd(px + k), x1 = _mm_loadu_pd(px + k - 1), x2 = _mm_loadu_pd(px + k - 2);
      const __m128d a = _mm_andnot_pd(sign, _mm_sub_pd(x0, x1));
      const __m128d b = _mm_andnot_pd(sign, _mm_add_pd(_mm_sub_pd(x0, _mm_mul_pd(two, x1)), x2));
      nan = _mm_or_pd(nan, _mm_or_pd(_mm_cmpunord_pd(a, a), _mm_cmpunord_pd(b, b)));
      m1 = _mm_max_pd(m1, a), m2 = _mm_max_pd(m2, b);
    }
    double v1[2], v2[2];
    _mm_storeu_pd(v1, m1);
    _mm_storeu_pd(v2, m2);
    ordered = _mm_movemask_pd(nan) == 0;
    d1_max = std::max({d1_max, v1[0], v1[1]}), d2_max = std::max({d2_max, v2[0], v2[1]});
  }
#endif
  if (!ordered) d1_max = 0, d2_max = 0, k = 1;  // a NaN seen: the whole fold again, in order
  for (; k < n; ++k) {  // the rows the vectors left, or every row
    d1_max = std::max(d1_max, std::abs(px[k] - px[k - 1]));
    if (k >= 2) d2_max = std::max(d2_max, std::abs(px[k] - 2 * px[k - 1] + px[k - 2]));
  }
}

DriveChecksAfter::DriveChecksAfter(const core::Machine& machine, const core::Setpoints& sp,
                                   const std::vector<bool>& cascade, const drives::GainSchedule* gains)
    : machine_(&machine), te_(sp.period_s), ns_(sp.samples()) {
  if (ns_ < 1) return;
  const double te = te_;
  const Eigen::Index ns = ns_;
  for (std::size_t i = 0; i < machine.axes.size(); ++i) {
    const core::MachineAxis& ax = machine.axes[i];
    const auto a = static_cast<Eigen::Index>(i);
    if (!ax.drive || i >= cascade.size() || !cascade[i] || !moves(sp, a)) continue;
    Axis x;
    x.index = i;
    x.params = *ax.drive;
    core::DriveParams& p = x.params;
    if (gains) {
      p.kv_per_s = lowest(gains->kv_per_s, a, p.kv_per_s);
      p.kf = lowest(gains->kf, a, p.kf);
    }
    const drives::DriveStability d = drives::drive_stability(p, te);
    // The setpoints' velocity and acceleration (backward differences, as the feedforward takes them).
    // The largest differences first, divided once: rounding is monotone, so max(|d| / te) is max(|d|) / te exactly.
    double d1_max = 0, d2_max = 0;
    largest_setpoint_differences(sp.position.col(a).data(), ns, d1_max, d2_max);
    const double v_max = d1_max / te, a_max = d2_max / (te * te);
    // The floor covers what the linear model leaves out and a careful drive still shows: Coulomb friction at
    // reversals, gravity, the current loop's voltage limit (a few um on the parts' machines).
    const double floor = ax.kind == core::AxisKind::Rotary ? 1e-4 : 0.01;
    x.bound = 3.0 * (std::abs(d.lag_s) * v_max + std::abs(d.lag_s2) * a_max) + floor;
    x.v_max = v_max, x.a_max = a_max;
    axes_.push_back(x);
  }
}

void DriveChecksAfter::add(Eigen::Index k0, const core::Setpoints& sp, const drives::AxisResponse& resp) {
  const Eigen::Index m = resp.samples();
  const double te = te_;
  for (Axis& x : axes_) {
    const auto a = static_cast<Eigen::Index>(x.index);
    if (a >= resp.position.cols()) continue;
    const double limit = x.params.current_limit_A;
    for (Eigen::Index r = 0; r < m; ++r) {
      const Eigen::Index k = k0 + r;
      const double e = std::abs(sp.position(std::min(k, ns_ - 1), a) - resp.position(r, a));
      if (!(e <= x.e_max)) x.e_max = e, x.e_row = static_cast<double>(k);  // NaN counts as the largest
      const bool sat = resp.current_setpoint_A.size() && std::abs(resp.current_setpoint_A(r, a)) >= limit * (1 - 1e-9);
      x.run = sat ? x.run + te : 0.0;
      x.saturated += sat ? te : 0.0;
      x.longest = std::max(x.longest, x.run);
    }
  }
}

void DriveChecksAfter::finish(DriveChecks& checks) const {
  const core::Machine& machine = *machine_;
  const double te = te_;
  for (const Axis& x : axes_) {
    const core::MachineAxis& ax = machine.axes[x.index];
    const core::DriveParams& p = x.params;
    const double bound = x.bound, e_max = x.e_max, e_row = x.e_row, saturated = x.saturated, longest = x.longest;
    const double v_max = x.v_max, a_max = x.a_max, limit = p.current_limit_A;
    nlohmann::json& fig = checks.axes[ax.name];
    fig["current_saturated_s"] = saturated;
    fig["current_saturated_longest_s"] = longest;
    fig[fmt::format("following_error_max_{}", unit(ax))] = e_max;
    fig[fmt::format("following_error_bound_{}", unit(ax))] = bound;
    const std::string where = fmt::format("{}: axis {}", machine.source_file, ax.name);
    if (longest >= 0.01)
      checks.warnings.push_back(
          {"current_saturation", ax.name,
           fmt::format("{}: the current setpoint stays at current_limit_A = {:g} A for {:.3g} s at a stretch ({:.3g} s "
                       "in all): the drive cannot give the acceleration the setpoints ask; the path and the marks "
                       "show what this drive does, not what the program asks (check current_limit_A and the axis' "
                       "max_acceleration)",
                       where, limit, longest, saturated)});
    const std::string fe = fmt::format(
        "{}: the following error reaches {:.4g} {} at t = {:.3f} s, while the drive's linear model "
        "(Kv = {:g} 1/s, KF = {:g}) bounds it by {:.4g} {} at the setpoints' {:.4g} {}/s and {:.4g} {}/s^2",
        where, e_max, unit(ax), e_row * te, p.kv_per_s, p.kf, bound, unit(ax), v_max, unit(ax), a_max, unit(ax));
    if (!(e_max <= 10 * bound))
      checks.warnings.push_back({"following_error_implausible", ax.name,
                                 fe + ": the axis did not follow its setpoints; the result cannot mean what it claims "
                                      "(check current_limit_A, voltage_limit_V, the friction and gravity torques)",
                                 core::Warning::Severity::Invalid});
    else if (e_max > bound)
      checks.warnings.push_back({"following_error_beyond_model", ax.name,
                                 fe + ": a limit of the drive (current, voltage) or its friction shapes the result"});
  }
}

void check_drives_after(const core::Machine& machine, const core::Setpoints& sp, const drives::AxisResponse& resp,
                        const std::vector<bool>& cascade, const drives::GainSchedule* gains, DriveChecks& checks) {
  DriveChecksAfter after(machine, sp, cascade, gains);
  after.add(0, sp, resp);
  after.finish(checks);
}

nlohmann::json warnings_json(const core::Warnings& warnings) {
  nlohmann::json out = nlohmann::json::array();
  for (const core::Warning& w : warnings)
    out.push_back({{"code", w.code},
                   {"severity", w.severity == core::Warning::Severity::Invalid ? "invalid" : "warning"},
                   {"subject", w.subject},
                   {"message", w.message}});
  return out;
}

void add_verdict(nlohmann::json& report, const core::Warnings& warnings) {
  report["warnings"] = warnings_json(warnings);
  report["verdict"] = core::verdict(warnings);
}

}  // namespace vmsim::sim
