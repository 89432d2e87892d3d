// Offline gain adjustment (Duong et al.); see oga.hpp for the algorithm, the departures from the seed and the limits.
#include "methods/oga.hpp"
#include "core/timing.hpp"

#include "core/error.hpp"
#include "core/units.hpp"
#include "drives/axis_model.hpp"
#include "drives/cascade_axis.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>

namespace vmsim::methods {

namespace {

using Index = Eigen::Index;
using core::units::kNaN;
using core::units::kInf;
constexpr double kKv = core::units::kKvMPerMinPerMmToPerS;  // (m/min)/mm -> 1/s
// motion::contour_error's index window: its largest default. The arc-length budget is the working limit of its
// search; a fixed cap makes every evaluation here (whole path, windows) the same computation.
constexpr int kContourWindow = 65536;

using Clock = std::chrono::steady_clock;
using core::seconds_since;

// ---- the profile every step shares -----------------------------------------------------------------------------

struct Profile {
  const core::Setpoints* sp = nullptr;
  const core::Machine* machine = nullptr;
  std::vector<int> axes;      // adjusted machine axes
  int xyz[3] = {-1, -1, -1};  // machine axis of X, Y, Z
  int col[2] = {0, 0};        // column (0..2) of each adjusted axis in the X Y Z matrices
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
  double te = 1e-3;
  Index n_set = 0, rows = 0;
  Eigen::MatrixXd command;  // rows x 3: X Y Z setpoints, the last one held over the settling rows
  Eigen::ArrayXd weight;    // rows
  double weight_sum = 0.0;
  motion::ContourOptions ce_options;

  double setpoint(int axis, Index k) const { return sp->position(std::min(k, n_set - 1), axis); }
};

Profile make_profile(const core::Setpoints& sp, const core::Machine& m, const OgaOptions& o) {
  Profile p;
  p.sp = &sp;
  p.machine = &m;
  p.te = sp.period_s;
  if (!(p.te > 0.0 && std::isfinite(p.te)))
    throw core::Error(fmt::format("OGA: the period Te must be positive, found {}", p.te));
  p.n_set = sp.samples();
  if (p.n_set < 4) throw core::Error("OGA: the setpoints have fewer than 4 samples: no profile to adjust gains on");
  if (sp.position.cols() != static_cast<Index>(m.axes.size()))
    throw core::Error(
        fmt::format("OGA: the setpoints have {} axes, the machine {}", sp.position.cols(), m.axes.size()));
  if (!sp.position.allFinite()) throw core::Error("OGA: a setpoint is not finite");
  if (!(o.settle_s >= 0.0 && std::isfinite(o.settle_s)))
    throw core::Error(fmt::format("OGA: settle_s must be >= 0, found {}", o.settle_s));
  p.rows = p.n_set + static_cast<Index>(std::llround(o.settle_s / p.te));
  for (int c = 0; c < 3; ++c) p.xyz[c] = m.axis_index(c);
  for (int c = 0; c < 3; ++c)
    if (p.xyz[c] < 0) throw core::Error(fmt::format("OGA: the machine has no {} axis", "XYZ"[c]));
  auto moves = [&](int a) { return (sp.position.col(a).array() != sp.position(0, a)).any(); };
  std::vector<int> fixed;
  for (int c = 0; c < 3; ++c) {
    const int a = p.xyz[c];
    if (moves(a)) {
      if (p.axes.size() < 2) p.col[p.axes.size()] = c;
      p.axes.push_back(a);
    } else {
      fixed.push_back(c);
    }
  }
  for (int a = 0; a < static_cast<int>(m.axes.size()); ++a)
    if (a != p.xyz[0] && a != p.xyz[1] && a != p.xyz[2] && moves(a))
      throw core::Error(
          fmt::format("OGA: axis {} moves; Duong et al.'s offline gain adjustment is for biaxial planar "
                      "profiles of two of X, Y, Z",
                      m.axes[static_cast<std::size_t>(a)].name));
  if (p.axes.size() != 2) {
    std::string names;
    for (int a : p.axes) names += (names.empty() ? "" : ", ") + m.axes[static_cast<std::size_t>(a)].name;
    throw core::Error(
        fmt::format("OGA: {} of X, Y, Z move ({}); Duong et al.'s offline gain adjustment needs a biaxial "
                    "planar profile: exactly two moving axes",
                    p.axes.size(), names.empty() ? "none" : names));
  }
  p.normal = Eigen::Vector3d::Zero();
  p.normal[fixed[0]] = 1.0;
  for (int a : p.axes) {
    const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(a)];
    if (!ax.drive)
      throw core::Error(
          core::located(m.source_file, 0, fmt::format("axis {} moves but has no [axes.drive] section", ax.name)));
  }
  p.command.resize(p.rows, 3);
  for (Index k = 0; k < p.rows; ++k)
    for (int c = 0; c < 3; ++c) p.command(k, c) = p.setpoint(p.xyz[c], k);
  if (o.row_weight.size() == 0) {
    p.weight = Eigen::ArrayXd::Ones(p.rows);
  } else {
    if (o.row_weight.size() != p.rows)
      throw core::Error(
          fmt::format("OGA: row_weight has {} entries, expected one per response row ({} = {} setpoints "
                      "+ {} settling rows)",
                      o.row_weight.size(), p.rows, p.n_set, p.rows - p.n_set));
    if (!(o.row_weight >= 0.0).all() || !o.row_weight.allFinite())
      throw core::Error("OGA: row_weight must be finite and >= 0");
    p.weight = o.row_weight;
  }
  p.weight_sum = p.weight.sum();
  if (!(p.weight_sum > 0.0)) throw core::Error("OGA: no row counts in MSE(CE) (row_weight is all zero)");
  p.ce_options.plane_normal = p.normal;
  p.ce_options.window_samples = kContourWindow;
  return p;
}

// ---- one axis driven row by row, with its frictionless twin -----------------------------------------------------

struct AxisTrack {
  std::unique_ptr<drives::AxisModel> drive, twin;
  double nc_x = 0.0, nc_v = 0.0;              // the NC's previous setpoint and velocity (feedforward differences)
  double fd_x = 0.0, fd_v = 0.0, fd_a = 0.0;  // the twin at the previous row: position, velocity, acceleration
  Index row = 0;                              // the row the state is at (before command `row`)

  AxisTrack clone() const {
    AxisTrack t;
    t.drive = drive->clone();
    t.twin = twin->clone();
    t.nc_x = nc_x, t.nc_v = nc_v, t.fd_x = fd_x, t.fd_v = fd_v, t.fd_a = fd_a, t.row = row;
    return t;
  }
};

core::DriveParams frictionless(const core::DriveParams& p) {
  core::DriveParams q = p;
  q.coulomb_Nm = 0.0;
  q.stribeck_static_Nm = 0.0;
  return q;
}

AxisTrack start_track(const core::MachineAxis& ax, double te, double x0) {
  AxisTrack t;
  t.drive = drives::make_cascade_axis(*ax.drive, te, ax.kind);
  t.drive->reset(x0);
  t.twin = drives::make_cascade_axis(frictionless(*ax.drive), te, ax.kind);
  t.twin->reset(x0);
  t.nc_x = x0;
  t.fd_x = x0;
  return t;
}

inline void raise(Peak& p, double v, Index row) {
  if (v > p.value || p.row < 0) p.value = v, p.row = row;
}

// Command `t.row` (setpoint x_d, gains kv 1/s and kf): the state moves to row t.row + 1. As simulate_axes: the
// feedforward set points are the backward differences of the setpoints, at rest before the first.
inline double step_track(AxisTrack& t, double x_d, double te, double kv, double kf, MotionPeaks& pk) {
  drives::AxisCommand c;
  c.position = x_d;
  c.velocity = (x_d - t.nc_x) / te;
  c.acceleration = (c.velocity - t.nc_v) / te;
  t.nc_x = x_d;
  t.nc_v = c.velocity;
  c.kv_per_s = kv;
  c.kf = kf;
  const drives::AxisSample s = t.drive->step(c);
  const drives::AxisSample w = t.twin->step(c);
  ++t.row;
  const double v = (w.position - t.fd_x) / te, a = (v - t.fd_v) / te, j = (a - t.fd_a) / te;
  t.fd_x = w.position, t.fd_v = v, t.fd_a = a;
  raise(pk.velocity, std::abs(v), t.row);
  raise(pk.acceleration, std::abs(a), t.row);
  raise(pk.jerk, std::abs(j), t.row);
  raise(pk.current, s.current_peak_A, t.row);
  return s.position;
}

std::string trade_units(double value, int kind) {  // linear axes: mm/s -> m/min, mm/s^2 -> m/s^2, ...
  switch (kind) {
    case 0:
      return fmt::format("{:.4g} m/min", value * 60.0 / 1000.0);
    case 1:
      return fmt::format("{:.4g} m/s^2", value / 1000.0);
    case 2:
      return fmt::format("{:.4g} m/s^3", value / 1000.0);
    default:
      return fmt::format("{:.4g} A", value);
  }
}

// Weighted sum of squared contour errors over actual rows [from, actual.rows()) (command and actual share their
// first row's instant, row `offset` of the whole response).
double weighted_sse(const motion::ContourError& ce, const Eigen::ArrayXd& weight, Index offset, Index from) {
  double s = 0.0;
  for (Index r = from; r < ce.signed_mm.size(); ++r) s += weight[offset + r] * ce.signed_mm[r] * ce.signed_mm[r];
  return s;
}

std::vector<double> default_grid(double lo, double step, double hi) {
  std::vector<double> g;
  const int n = static_cast<int>(std::floor((hi - lo) / step + 1e-9));
  for (int i = 0; i <= n; ++i) g.push_back(lo + i * step);
  return g;
}

// Candidate final gains of one axis in one window (Duong et al. eq. 3: K(k-1) + 2A, A on [Kmin - K(k-1) : dK :
// Kmax - K(k-1)] / 2, i.e. Kmin + i dK), the previous gain first when the grid misses it.
std::vector<double> candidate_gains(double k_prev, std::pair<double, double> range, double step) {
  std::vector<double> g;
  const std::vector<double> grid = default_grid(range.first, step, range.second);
  const bool on_grid = std::any_of(grid.begin(), grid.end(), [&](double v) { return std::abs(v - k_prev) <= 1e-12; });
  if (!on_grid && k_prev >= range.first - 1e-12 && k_prev <= range.second + 1e-12) g.push_back(k_prev);
  // On the grid, the previous gain goes first as well, so that ties keep it.
  for (double v : grid)
    if (std::abs(v - k_prev) <= 1e-12) g.insert(g.begin(), v);
  for (double v : grid)
    if (std::abs(v - k_prev) > 1e-12) g.push_back(v);
  return g;
}

// Windows of at least p commands covering [0, end): a window shorter than p takes the commands after it up to p
// (a following window left shorter than p joins it whole); a last window shorter than p joins the one before. The
// sinusoid of eq. 3 then always completes, with the gain's slope zero at both of its ends: a window cut short
// would leave the gain changing, and the next window's first gain (equal to it, eq. 3) would stop it at once, a
// kink in Kv, i.e. a step in the derivative of the velocity command and a jerk spike (42 to 69 m/s^3 on the X axis
// of the OGA profile, against its 10 m/s^3).
std::vector<Window> at_least_p(const std::vector<Window>& in, Index p, Index end) {
  std::vector<Window> out;
  Index next = 0;  // first command not yet in a window
  for (std::size_t i = 0; i < in.size() && next < end; ++i) {
    Window w = in[i];
    w.begin = next;
    w.end = std::min(w.end, end);
    if (w.end <= w.begin) continue;
    if (w.end - w.begin < p) w.end = std::min(end, w.begin + p);
    // Windows the extension reaches into: trimmed, or absorbed when too little of them is left.
    while (i + 1 < in.size() && in[i + 1].begin < w.end) {
      const Index rest = std::min(in[i + 1].end, end) - w.end;
      if (rest >= p) break;
      w.end = std::max(w.end, std::min(in[i + 1].end, end));
      ++i;
    }
    out.push_back(w);
    next = w.end;
  }
  if (!out.empty() && out.back().end < end) out.back().end = end;
  if (out.size() > 1 && out.back().end - out.back().begin < p) {
    out[out.size() - 2].end = out.back().end;
    out.pop_back();
  }
  return out;
}

}  // namespace

// ---- windows -------------------------------------------------------------------------------------------------------

const char* window_kind_name(WindowKind kind) {
  switch (kind) {
    case WindowKind::Straight:
      return "straight";
    case WindowKind::Convex:
      return "convex";
    case WindowKind::Concave:
      return "concave";
    case WindowKind::Transition:
      return "transition";
  }
  return "?";
}

namespace {

// Arc length at each row, and for each row the neighbours at least `h` of arc length away (-1: none).
struct Neighbours {
  Eigen::ArrayXd s;
  std::vector<Index> before, after;
};

Neighbours chord_neighbours(const Eigen::MatrixXd& xyz, double h) {
  const Index n = xyz.rows();
  Neighbours nb;
  nb.s.setZero(n);
  for (Index k = 1; k < n; ++k) nb.s[k] = nb.s[k - 1] + (xyz.row(k) - xyz.row(k - 1)).norm();
  nb.before.assign(static_cast<std::size_t>(n), -1);
  nb.after.assign(static_cast<std::size_t>(n), -1);
  Index i = -1, j = 0;
  for (Index k = 0; k < n; ++k) {
    while (i + 1 < k && nb.s[i + 1] <= nb.s[k] - h) ++i;  // largest i with s_i <= s_k - h
    if (i >= 0 && nb.s[i] <= nb.s[k] - h) nb.before[static_cast<std::size_t>(k)] = i;
    if (j <= k) j = k + 1;
    while (j < n && nb.s[j] < nb.s[k] + h) ++j;  // smallest j with s_j >= s_k + h
    if (j < n) nb.after[static_cast<std::size_t>(k)] = j;
  }
  return nb;
}

void fill_undefined(Eigen::ArrayXd& v) {
  const Index n = v.size();
  Index first = -1;
  for (Index k = 0; k < n; ++k)
    if (!std::isnan(v[k])) {
      first = k;
      break;
    }
  if (first < 0) {
    v.setZero();
    return;
  }
  for (Index k = 0; k < first; ++k) v[k] = v[first];
  for (Index k = first + 1; k < n; ++k)
    if (std::isnan(v[k])) v[k] = v[k - 1];
}

}  // namespace

Eigen::ArrayXd setpoint_curvature(const Eigen::MatrixXd& xyz, const Eigen::Vector3d& n, double min_chord_mm) {
  if (xyz.cols() != 3) throw core::Error("setpoint_curvature: expected rows x 3 (X Y Z, mm)");
  if (!(min_chord_mm > 0.0)) throw core::Error("setpoint_curvature: min_chord_mm must be positive");
  const Eigen::Vector3d nu = n.normalized();
  const Neighbours nb = chord_neighbours(xyz, min_chord_mm);
  Eigen::ArrayXd kappa = Eigen::ArrayXd::Constant(xyz.rows(), kNaN);
  for (Index k = 0; k < xyz.rows(); ++k) {
    const Index i = nb.before[static_cast<std::size_t>(k)], j = nb.after[static_cast<std::size_t>(k)];
    if (i < 0 || j < 0) continue;
    const Eigen::Vector3d a = (xyz.row(k) - xyz.row(i)).transpose(), b = (xyz.row(j) - xyz.row(k)).transpose();
    const double den = a.norm() * b.norm() * (a + b).norm();
    if (!(den > 0.0)) continue;
    kappa[k] = 2.0 * a.cross(b).dot(nu) / den;  // the circle through the three points, signed about n
  }
  fill_undefined(kappa);
  return kappa;
}

std::vector<Window> curvature_windows(const Eigen::MatrixXd& xyz, const Eigen::Vector3d& n, const WindowOptions& o) {
  if (!(o.straight_curvature_per_mm >= 0.0 && o.transition_rate_per_mm2 > 0.0 && o.min_rows >= 1))
    throw core::Error("curvature_windows: thresholds must be positive and min_rows >= 1");
  const Index rows = xyz.rows();
  std::vector<Window> w;
  if (rows == 0) return w;
  const Eigen::ArrayXd kappa = setpoint_curvature(xyz, n, o.min_chord_mm);
  const Neighbours nb = chord_neighbours(xyz, o.min_chord_mm);
  for (Index k = 0; k < rows; ++k) {
    const Index i = nb.before[static_cast<std::size_t>(k)], j = nb.after[static_cast<std::size_t>(k)];
    double rate = 0.0;
    if (i >= 0 && j >= 0) rate = std::abs(kappa[j] - kappa[i]) / (nb.s[j] - nb.s[i]);
    WindowKind kind = WindowKind::Straight;
    if (rate > o.transition_rate_per_mm2)
      kind = WindowKind::Transition;
    else if (kappa[k] > o.straight_curvature_per_mm)
      kind = WindowKind::Convex;
    else if (kappa[k] < -o.straight_curvature_per_mm)
      kind = WindowKind::Concave;
    if (!w.empty() && w.back().kind == kind)
      w.back().end = k + 1;
    else
      w.push_back({k, k + 1, kind});
  }
  // Short runs join the window before (a short first one joins the next); equal neighbours merge.
  std::vector<Window> merged;
  for (const Window& x : w) {
    if (merged.empty()) {
      merged.push_back(x);
      continue;
    }
    Window& last = merged.back();
    if (x.end - x.begin < o.min_rows || last.kind == x.kind)
      last.end = x.end;
    else if (last.end - last.begin < o.min_rows)
      last = {last.begin, x.end, x.kind};
    else
      merged.push_back(x);
  }
  return merged;
}

// ---- gain function -------------------------------------------------------------------------------------------------

int sinusoid_samples(double frequency_hz, double te_s) {
  if (!(frequency_hz > 0.0 && std::isfinite(frequency_hz) && te_s > 0.0))
    throw core::Error(fmt::format("OGA: the gain frequency f must be positive, found {} Hz", frequency_hz));
  const double p = 1.0 / (2.0 * frequency_hz * te_s);
  if (!(p >= 1.5))
    throw core::Error(
        fmt::format("OGA: the gain frequency f = {} Hz is too high for Te = {} ms: the sinusoid of eq. 3 "
                    "would be shorter than 2 samples (f <= 1 / (4 Te) = {} Hz)",
                    frequency_hz, te_s * 1e3, 1.0 / (4.0 * te_s)));
  if (p > 1e7) throw core::Error(fmt::format("OGA: the gain frequency f = {} Hz is too low", frequency_hz));
  return static_cast<int>(std::lround(p));
}

void gain_function(double k_prev, double k_final, int p, Index n, double* out) {
  if (p < 2) throw core::Error("gain_function: p must be >= 2");
  const double a = (k_final - k_prev) / 2.0;  // A_i of eq. 3
  double last = k_prev;
  for (Index i = 0; i < n; ++i) {
    if (i < p) {
      // 2 pi f t_i with f = 1/(2 p Te) and t_i = p Te (1/2 + i/(p-1)): pi (1/2 + i/(p-1)), from pi/2 to 3 pi/2.
      const double phase = std::numbers::pi * (0.5 + static_cast<double>(i) / (p - 1));
      last = i == 0 ? k_prev : i == p - 1 ? k_final : -a * std::sin(phase) + a + k_prev;
    }
    out[i] = last;  // eq. 4 beyond p: the last value of the sinusoidal part
  }
}

// ---- limits ---------------------------------------------------------------------------------------------------------

std::string limit_set_name(const LimitSet& l) {
  std::string s;
  for (const auto& [on, name] : {std::pair{l.velocity, "velocity"}, std::pair{l.acceleration, "acceleration"},
                                 std::pair{l.jerk, "jerk"}, std::pair{l.current, "current"}})
    if (on) s += (s.empty() ? "" : ",") + std::string(name);
  return s.empty() ? "none" : s;
}

LimitSet parse_limit_set(const std::string& text) {
  if (text == "all") return {};
  LimitSet l{false, false, false, false};
  if (text == "none") return l;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    const std::string w = text.substr(at, end - at);
    if (w == "velocity")
      l.velocity = true;
    else if (w == "acceleration")
      l.acceleration = true;
    else if (w == "jerk")
      l.jerk = true;
    else if (w == "current")
      l.current = true;
    else
      throw core::Error(
          fmt::format("limits \"{}\": unknown limit \"{}\" (expected a comma-separated list of "
                      "velocity, acceleration, jerk, current; or all, none)",
                      text, w));
    at = end + 1;
  }
  return l;
}

double limit_ratio(const MotionPeaks& p, const core::MachineAxis& ax, const LimitSet& l) {
  double r = 0.0;
  if (l.velocity) r = std::max(r, p.velocity.value / ax.max_velocity);
  if (l.acceleration) r = std::max(r, p.acceleration.value / ax.max_acceleration);
  if (l.jerk) r = std::max(r, p.jerk.value / ax.max_jerk);
  if (l.current && ax.drive) r = std::max(r, p.current.value / ax.drive->current_limit_A);
  return r;
}

std::string limit_violation(const MotionPeaks& p, const core::MachineAxis& ax, double te, const LimitSet& l) {
  const Peak* peaks[3] = {&p.velocity, &p.acceleration, &p.jerk};
  const double limits[3] = {ax.max_velocity, ax.max_acceleration, ax.max_jerk};
  const bool on[3] = {l.velocity, l.acceleration, l.jerk};
  const char* names[3] = {"velocity", "acceleration", "jerk"};
  for (int q = 0; q < 3; ++q)
    if (on[q] && !(peaks[q]->value <= limits[q]))
      return fmt::format("{} {} > {} at t {:.3f} s", names[q], trade_units(peaks[q]->value, q),
                         trade_units(limits[q], q), peaks[q]->row * te);
  if (l.current && ax.drive && !(p.current.value < ax.drive->current_limit_A))
    return fmt::format("current {:.4g} A >= the limit {:.4g} A at t {:.3f} s", p.current.value,
                       ax.drive->current_limit_A, p.current.row * te);
  return "";
}

namespace {
// The peak that breaks a limit, in limit_violation's order; null when none does.
const Peak* broken_peak(const MotionPeaks& p, const core::MachineAxis& ax) {
  if (!(p.velocity.value <= ax.max_velocity)) return &p.velocity;
  if (!(p.acceleration.value <= ax.max_acceleration)) return &p.acceleration;
  if (!(p.jerk.value <= ax.max_jerk)) return &p.jerk;
  if (ax.drive && !(p.current.value < ax.drive->current_limit_A)) return &p.current;
  return nullptr;
}
}  // namespace

MotionPeaks finite_difference_motion_peaks(const Eigen::VectorXd& x, double te, Index first) {
  MotionPeaks pk;
  double px = x.size() > 0 ? x[0] : 0.0, pv = 0.0, pa = 0.0;
  for (Index k = 0; k < x.size(); ++k) {
    const double v = (x[k] - px) / te, a = (v - pv) / te, j = (a - pa) / te;
    px = x[k], pv = v, pa = a;
    if (k < first) continue;
    raise(pk.velocity, std::abs(v), k);
    raise(pk.acceleration, std::abs(a), k);
    raise(pk.jerk, std::abs(j), k);
  }
  return pk;
}

// ---- the search
// ------------------------------------------------------------------------------------------------------

OgaResult offline_gain_adjustment(const core::Setpoints& sp, const core::Machine& m, const OgaOptions& o) {
  const auto t_start = Clock::now();
  const auto say = [&](const std::string& s) {
    if (o.progress) o.progress(s);
  };
  const Profile P = make_profile(sp, m, o);
  OgaResult res;
  res.axes = P.axes;
  for (int a : P.axes) res.axis_names.push_back(m.axes[static_cast<std::size_t>(a)].name);
  res.plane_normal = P.normal;
  res.period_s = P.te;
  res.rows = P.rows;
  res.kp_grid = o.kp_grid.empty() ? default_grid(1.0, 0.5, 9.0) : o.kp_grid;
  res.kf_grid = o.kf_grid.empty() ? default_grid(0.0, 0.1, 1.2) : o.kf_grid;
  for (double v : res.kp_grid)
    if (!(v > 0.0 && std::isfinite(v))) throw core::Error(fmt::format("OGA: Kp grid value {} is not a gain > 0", v));
  for (double v : res.kf_grid)
    if (!(v >= 0.0 && std::isfinite(v))) throw core::Error(fmt::format("OGA: KF grid value {} is not >= 0", v));
  if (!(o.gain_step > 0.0 && std::isfinite(o.gain_step)))
    throw core::Error(fmt::format("OGA: the gain step dK must be positive, found {}", o.gain_step));
  if (o.lead_in_rows < 0) throw core::Error("OGA: lead_in_rows must be >= 0");
  for (const auto& [name, r] : o.range) {
    if (std::find(res.axis_names.begin(), res.axis_names.end(), name) == res.axis_names.end())
      throw core::Error(fmt::format("OGA: a range is given for axis {}, which the profile does not move", name));
    if (!(r.first > 0.0 && r.second >= r.first && std::isfinite(r.second)))
      throw core::Error(
          fmt::format("OGA: the range [{}, {}] of axis {} is not 0 < min <= max", r.first, r.second, name));
  }
  res.sinusoid_samples = sinusoid_samples(o.frequency_hz, P.te);
  const int p = res.sinusoid_samples;
  const Index R = P.rows, N = P.n_set;
  const std::size_t n_kp = res.kp_grid.size(), n_kf = res.kf_grid.size(), n_cfg = n_kp * n_kf;
  const core::MachineAxis* ax[2] = {&m.axes[static_cast<std::size_t>(P.axes[0])],
                                    &m.axes[static_cast<std::size_t>(P.axes[1])]};
  for (int q = 0; q < 2; ++q) (void)start_track(*ax[q], P.te, P.setpoint(P.axes[q], 0));  // errors before the work

  // 1. Admissible gains (Duong et al. section III.D): every configuration on the whole profile, axis by axis.
  auto t0 = Clock::now();
  say(fmt::format("admissible gains: {} configurations x {} axes on {} rows", n_cfg, 2, R));
  res.sweep.assign(2, std::vector<ConfigCheck>(n_cfg));
  std::vector<std::vector<Eigen::VectorXd>> path(2, std::vector<Eigen::VectorXd>(n_cfg));
  {
    const int tasks = static_cast<int>(2 * n_cfg);
#pragma omp parallel for schedule(dynamic, 1)
    for (int task = 0; task < tasks; ++task) {
      const int q = task / static_cast<int>(n_cfg);
      const std::size_t c = static_cast<std::size_t>(task) % n_cfg;
      ConfigCheck& cc = res.sweep[static_cast<std::size_t>(q)][c];
      cc.gains = {res.kp_grid[c / n_kf], res.kf_grid[c % n_kf]};
      const int a = P.axes[static_cast<std::size_t>(q)];
      AxisTrack t = start_track(*ax[q], P.te, P.setpoint(a, 0));
      Eigen::VectorXd& x = path[static_cast<std::size_t>(q)][c];
      x.resize(R);
      x[0] = P.setpoint(a, 0);
      for (Index k = 0; k + 1 < R; ++k)
        x[k + 1] = step_track(t, P.setpoint(a, k), P.te, cc.gains.kp * kKv, cc.gains.kf, cc.twin);
      cc.violation = x.allFinite() ? limit_violation(cc.twin, *ax[q], P.te, o.limits) : "the motion diverges";
      cc.admissible = cc.violation.empty();
      cc.model = finite_difference_motion_peaks(x, P.te);
      cc.model.current = cc.twin.current;
    }
  }
  res.timings_s["admissible_gains"] = seconds_since(t0);

  // 2. The best fixed pair: every admissible configuration of one axis with every one of the other.
  t0 = Clock::now();
  std::vector<std::size_t> adm[2];
  for (int q = 0; q < 2; ++q)
    for (std::size_t c = 0; c < n_cfg; ++c)
      if (res.sweep[static_cast<std::size_t>(q)][c].admissible) adm[q].push_back(c);
  const auto whole_path_mse = [&](const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) {
    Eigen::MatrixXd act = P.command;
    act.col(P.col[0]) = x0;
    act.col(P.col[1]) = x1;
    const motion::ContourError ce = motion::contour_error(P.command, act, P.ce_options);
    return weighted_sse(ce, P.weight, 0, 0) / P.weight_sum * 1e6;
  };
  if (!o.search_best_pair && o.reference == OgaOptions::Reference::Best)
    throw core::Error("OGA: C1 is the best fixed pair, so the pair search cannot be left out");
  res.pairs_evaluated = o.search_best_pair ? static_cast<Index>(adm[0].size() * adm[1].size()) : 0;
  res.best_mse_um2 = kNaN;
  if (o.search_best_pair)
    say(fmt::format("best fixed pair: {} x {} admissible configurations", adm[0].size(), adm[1].size()));
  std::optional<std::pair<std::size_t, std::size_t>> best_pair;
  if (res.pairs_evaluated > 0) {
    std::vector<double> mse(static_cast<std::size_t>(res.pairs_evaluated), kInf);
    const Index n1 = static_cast<Index>(adm[1].size());
    // This process's share of the pairs (all of them in one process); the others' come through o.share.combine.
    const Index share_count = std::max(1, o.share.count);
    if (o.share.index < 0 || o.share.index >= share_count)
      throw core::Error(fmt::format("OGA: process {} of {}", o.share.index, share_count));
    const Index i_begin = res.pairs_evaluated * o.share.index / share_count;
    const Index i_end = res.pairs_evaluated * (o.share.index + 1) / share_count;
#pragma omp parallel for schedule(dynamic, 4)
    for (Index i = i_begin; i < i_end; ++i) {
      try {
        mse[static_cast<std::size_t>(i)] = whole_path_mse(path[0][adm[0][static_cast<std::size_t>(i / n1)]],
                                                          path[1][adm[1][static_cast<std::size_t>(i % n1)]]);
      } catch (const core::Error&) {
        // a diverging motion: never the best
      }
    }
    if (share_count > 1) {
      if (!o.share.combine) throw core::Error("OGA: a pair search spread over processes needs their combine step");
      o.share.combine(mse);
    }
    const auto it = std::min_element(mse.begin(), mse.end());  // the first of equal values: deterministic
    const Index i = it - mse.begin();
    best_pair = {adm[0][static_cast<std::size_t>(i / n1)], adm[1][static_cast<std::size_t>(i % n1)]};
    res.best = {res.sweep[0][best_pair->first].gains, res.sweep[1][best_pair->second].gains};
    res.best_mse_um2 = *it;
  }
  res.timings_s["best_fixed_pair"] = seconds_since(t0);

  // C1: the best pair, or the machine file's gains.
  Eigen::VectorXd c1_path[2];
  if (o.reference == OgaOptions::Reference::Best) {
    if (!best_pair)
      throw core::Error(
          fmt::format("OGA: no admissible configuration on axis {} (e.g. {}): there is no best fixed pair; "
                      "see the sweep, or use the machine's own gains as C1",
                      adm[0].empty() ? res.axis_names[0] : res.axis_names[1],
                      (adm[0].empty() ? res.sweep[0] : res.sweep[1]).front().violation));
    res.c1 = res.best;
    c1_path[0] = path[0][best_pair->first];
    c1_path[1] = path[1][best_pair->second];
    res.c1_mse_um2 = res.best_mse_um2;
  } else {
    for (int q = 0; q < 2; ++q) {
      const AxisGains g{ax[q]->drive->kv_per_s / kKv, ax[q]->drive->kf};
      res.c1.push_back(g);
      const int a = P.axes[static_cast<std::size_t>(q)];
      AxisTrack t = start_track(*ax[q], P.te, P.setpoint(a, 0));
      MotionPeaks unused;
      c1_path[q].resize(R);
      c1_path[q][0] = P.setpoint(a, 0);
      for (Index k = 0; k + 1 < R; ++k)
        c1_path[q][k + 1] = step_track(t, P.setpoint(a, k), P.te, g.kp * kKv, g.kf, unused);
    }
    res.c1_mse_um2 = whole_path_mse(c1_path[0], c1_path[1]);
  }
  path.clear();

  // Ranges: given, or Duong et al.'s placement around C1 within the contiguous admissible Kp at C1's KF.
  for (int q = 0; q < 2; ++q) {
    const double k1 = res.c1[static_cast<std::size_t>(q)].kp;
    if (auto it = o.range.find(res.axis_names[static_cast<std::size_t>(q)]); it != o.range.end()) {
      res.range.push_back(it->second);
    } else {
      double lo = k1 - 1.0, hi = k1 + 0.5;
      // The grid KF nearest C1's and the run of admissible Kp around C1's.
      std::size_t f = 0;
      for (std::size_t j = 1; j < n_kf; ++j)
        if (std::abs(res.kf_grid[j] - res.c1[static_cast<std::size_t>(q)].kf) <
            std::abs(res.kf_grid[f] - res.c1[static_cast<std::size_t>(q)].kf))
          f = j;
      std::size_t near = 0;
      for (std::size_t i = 1; i < n_kp; ++i)
        if (std::abs(res.kp_grid[i] - k1) < std::abs(res.kp_grid[near] - k1)) near = i;
      const auto ok = [&](std::size_t i) { return res.sweep[static_cast<std::size_t>(q)][i * n_kf + f].admissible; };
      if (ok(near)) {
        std::size_t i0 = near, i1 = near;
        while (i0 > 0 && ok(i0 - 1)) --i0;
        while (i1 + 1 < n_kp && ok(i1 + 1)) ++i1;
        lo = std::max(lo, std::min(res.kp_grid[i0], k1));
        hi = std::min(hi, std::max(res.kp_grid[i1], k1));
      }
      res.range.push_back({lo, hi});
    }
    const auto& r = res.range.back();
    if (!(k1 >= r.first - 1e-12 && k1 <= r.second + 1e-12))
      throw core::Error(
          fmt::format("OGA: the range [{:g}, {:g}] of axis {} does not hold C1's Kp = {:g} (m/min)/mm: "
                      "the schedule starts from C1's gain (eq. 3: a window's first gain is the last of "
                      "the one before)",
                      r.first, r.second, res.axis_names[static_cast<std::size_t>(q)], k1));
  }

  // C1 as a constant schedule; C2 starts from it.
  res.c1_table.axis_names = res.axis_names;
  res.c1_table.kv_1000_per_min.resize(N, 2);
  res.c1_table.kf.resize(N, 2);
  for (int q = 0; q < 2; ++q) {
    res.c1_table.kv_1000_per_min.col(q).setConstant(res.c1[static_cast<std::size_t>(q)].kp);
    res.c1_table.kf.col(q).setConstant(res.c1[static_cast<std::size_t>(q)].kf);
  }
  res.c1_schedule = to_gain_schedule(res.c1_table, m);

  // 3. Windows (Duong et al. section III.E), on the setpoint rows; the last one also holds the settling commands.
  t0 = Clock::now();
  std::vector<Window> windows = at_least_p(curvature_windows(P.command.topRows(N), P.normal, o.windows), p, R - 1);
  say(fmt::format(
      "receding windows: {} windows, p = {} samples, {}", windows.size(), p,
      o.from_start ? "each candidate from the start (Duong et al.)" : "from the state at each window start"));

  // 4. Receding windows without overlap.
  AxisTrack track[2] = {start_track(*ax[0], P.te, P.setpoint(P.axes[0], 0)),
                        start_track(*ax[1], P.te, P.setpoint(P.axes[1], 0))};
  double k_prev[2] = {res.c1[0].kp, res.c1[1].kp};
  const double kf[2] = {res.c1[0].kf, res.c1[1].kf};
  Eigen::MatrixXd actual = P.command;  // the decided motion (X Y Z), filled window by window
  std::vector<double> kp_sched[2] = {std::vector<double>(static_cast<std::size_t>(N), k_prev[0]),
                                     std::vector<double>(static_cast<std::size_t>(N), k_prev[1])};
  double sse_total = 0.0;  // row 0: at rest on the first setpoint, contour error 0

  struct Candidate {
    double final_kp = 0.0;      // the gain eq. 3 aims at
    std::vector<double> gains;  // commands [a, min(b, N))
    Eigen::VectorXd x;          // rows a+1 .. b
    MotionPeaks peaks;
    AxisTrack end;
    bool ok = false;
    double ratio = kInf;
    std::string violation;
  };

  for (std::size_t wi = 0; wi < windows.size(); ++wi) {
    const Window& w = windows[wi];
    const Index a = w.begin, b = w.end, nc = b - a, ng = std::min(b, N) - a;
    // Task 1: the candidates' gains (eq. 3-4).
    std::vector<Candidate> cand[2];
    for (int q = 0; q < 2; ++q) {
      for (double g : candidate_gains(k_prev[q], res.range[static_cast<std::size_t>(q)], o.gain_step)) {
        Candidate c;
        c.final_kp = g;
        c.gains.resize(static_cast<std::size_t>(ng));
        gain_function(k_prev[q], g, p, ng, c.gains.data());
        cand[q].push_back(std::move(c));
      }
    }
    // Task 2: each candidate to the end of the window with the nonlinear model (and its twin).
    const int n0 = static_cast<int>(cand[0].size()), tasks = n0 + static_cast<int>(cand[1].size());
#pragma omp parallel for schedule(dynamic, 1)
    for (int task = 0; task < tasks; ++task) {
      const int q = task < n0 ? 0 : 1;
      Candidate& c = cand[q][static_cast<std::size_t>(task < n0 ? task : task - n0)];
      const int axis = P.axes[static_cast<std::size_t>(q)];
      MotionPeaks before;
      AxisTrack t;
      if (o.from_start) {
        t = start_track(*ax[q], P.te, P.setpoint(axis, 0));
        for (Index k = 0; k < a; ++k)
          step_track(t, P.setpoint(axis, k), P.te, kp_sched[q][static_cast<std::size_t>(k)] * kKv, kf[q], before);
      } else {
        t = track[q].clone();
      }
      c.x.resize(nc);
      for (Index k = a; k < b; ++k) {
        const double g = c.gains[static_cast<std::size_t>(std::min(k, N - 1) - a)];
        c.x[k - a] = step_track(t, P.setpoint(axis, k), P.te, g * kKv, kf[q], c.peaks);
      }
      c.ok = c.x.allFinite();
      c.violation = c.ok ? limit_violation(c.peaks, *ax[q], P.te, o.limits) : "the motion diverges";
      c.ratio = c.ok ? limit_ratio(c.peaks, *ax[q], o.limits) : kInf;
      c.ok = c.violation.empty();
      c.end = std::move(t);
    }
    OgaWindowResult wr;
    wr.window = w;
    std::vector<int> usable[2];
    for (int q = 0; q < 2; ++q) {
      for (int i = 0; i < static_cast<int>(cand[q].size()); ++i)
        if (cand[q][static_cast<std::size_t>(i)].ok) usable[q].push_back(i);
      wr.candidates.push_back(static_cast<int>(cand[q].size()));
      wr.within_limits.push_back(static_cast<int>(usable[q].size()));
      if (usable[q].empty()) {
        int least = 0;
        for (int i = 1; i < static_cast<int>(cand[q].size()); ++i)
          if (cand[q][static_cast<std::size_t>(i)].ratio < cand[q][static_cast<std::size_t>(least)].ratio) least = i;
        usable[q].push_back(least);
        wr.note += fmt::format("{}every candidate of axis {} breaks a limit; kept the least: {}",
                               wr.note.empty() ? "" : "; ", res.axis_names[static_cast<std::size_t>(q)],
                               cand[q][static_cast<std::size_t>(least)].violation);
      }
    }
    // Task 3: the contour error of the window for every combination; the rows before it are the motion decided.
    const Index c0 = std::max<Index>(0, a + 1 - o.lead_in_rows), c_end = std::min(R, b + 1 + o.lead_in_rows);
    const Eigen::MatrixXd cmd = P.command.middleRows(c0, c_end - c0);
    const Index n1 = static_cast<Index>(usable[1].size()), combos = static_cast<Index>(usable[0].size()) * n1;
    std::vector<double> sse(static_cast<std::size_t>(combos + 1), kInf);  // + the hold combination (0, 0)
#pragma omp parallel
    {
      Eigen::MatrixXd act = actual.middleRows(c0, b + 1 - c0);
#pragma omp for schedule(dynamic, 8)
      for (Index i = 0; i <= combos; ++i) {
        const int i0 = i < combos ? usable[0][static_cast<std::size_t>(i / n1)] : 0;
        const int i1 = i < combos ? usable[1][static_cast<std::size_t>(i % n1)] : 0;
        act.col(P.col[0]).tail(nc) = cand[0][static_cast<std::size_t>(i0)].x;
        act.col(P.col[1]).tail(nc) = cand[1][static_cast<std::size_t>(i1)].x;
        try {
          const motion::ContourError ce = motion::contour_error(cmd, act, P.ce_options);
          sse[static_cast<std::size_t>(i)] = weighted_sse(ce, P.weight, c0, a + 1 - c0);
        } catch (const core::Error&) {
          // a diverging candidate is never chosen
        }
      }
    }
    // Task 4: the least MSE(CE) over the window (the first of equal values: the previous gains come first).
    const auto best = std::min_element(sse.begin(), sse.begin() + combos) - sse.begin();
    if (!std::isfinite(sse[static_cast<std::size_t>(best)]))
      throw core::Error(fmt::format("OGA: window {} (rows {} to {}): every candidate's motion diverges", wi, a, b));
    const int pick[2] = {usable[0][static_cast<std::size_t>(best / n1)],
                         usable[1][static_cast<std::size_t>(best % n1)]};
    const double wsum = P.weight.segment(a + 1, nc).sum();
    wr.mse_um2 = wsum > 0 ? sse[static_cast<std::size_t>(best)] / wsum * 1e6 : 0.0;
    wr.hold_mse_um2 = wsum > 0 ? sse[static_cast<std::size_t>(combos)] / wsum * 1e6 : 0.0;
    sse_total += sse[static_cast<std::size_t>(best)];
    for (int q = 0; q < 2; ++q) {
      Candidate& c = cand[q][static_cast<std::size_t>(pick[q])];
      wr.final_kp.push_back(c.final_kp);
      wr.last_kp.push_back(c.gains.back());
      std::copy(c.gains.begin(), c.gains.end(), kp_sched[q].begin() + a);
      actual.col(P.col[q]).segment(a + 1, nc) = c.x;
      k_prev[q] = c.gains.back();
      track[q] = std::move(c.end);
    }
    res.windows.push_back(std::move(wr));
  }
  res.table = res.c1_table;
  for (int q = 0; q < 2; ++q)
    for (Index k = 0; k < N; ++k) res.table.kv_1000_per_min(k, q) = kp_sched[q][static_cast<std::size_t>(k)];
  res.schedule = to_gain_schedule(res.table, m);
  res.c2_mse_um2 = sse_total / P.weight_sum * 1e6;
  res.timings_s["windows"] = seconds_since(t0);
  res.timings_s["total"] = seconds_since(t_start);
  return res;
}

// ---- verification
// ------------------------------------------------------------------------------------------------------

OgaVerification verify_oga(const core::Setpoints& sp, const core::Machine& m, const OgaResult& res,
                           const OgaOptions& o) {
  const Profile P = make_profile(sp, m, o);
  if (P.axes != res.axes) throw core::Error("verify_oga: the result is for another profile (its axes differ)");
  OgaVerification v;
  drives::SimulateOptions so;
  so.settle_s = o.settle_s;
  core::Machine twin = m;
  for (int a : P.axes) {
    core::MachineAxis& ax = twin.axes[static_cast<std::size_t>(a)];
    ax.drive = frictionless(*ax.drive);
  }
  so.gains = &res.c1_schedule;
  v.c1 = drives::simulate_axes(sp, m, so);
  const drives::AxisResponse t1 = drives::simulate_axes(sp, twin, so);
  so.gains = &res.schedule;
  v.c2 = drives::simulate_axes(sp, m, so);
  const drives::AxisResponse t2 = drives::simulate_axes(sp, twin, so);

  const auto contour = [&](const drives::AxisResponse& r, double& mse, double& mx) {
    Eigen::MatrixXd act(r.samples(), 3);
    for (int c = 0; c < 3; ++c) act.col(c) = r.position.col(P.xyz[c]);
    motion::ContourError ce = motion::contour_error(P.command, act, P.ce_options);
    mse = weighted_sse(ce, P.weight, 0, 0) / P.weight_sum * 1e6;
    mx = 0.0;
    for (Index k = 0; k < ce.signed_mm.size(); ++k)
      if (P.weight[k] > 0) mx = std::max(mx, std::abs(ce.signed_mm[k]));
    return ce;
  };
  v.ce_c1 = contour(v.c1, v.mse_c1_um2, v.max_c1_mm);
  v.ce_c2 = contour(v.c2, v.mse_c2_um2, v.max_c2_mm);

  for (std::size_t q = 0; q < P.axes.size(); ++q) {
    const int a = P.axes[q];
    const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(a)];
    AxisVerification av;
    av.axis = ax.name;
    const auto peaks = [&](const drives::AxisResponse& kin, const drives::AxisResponse& model) {
      MotionPeaks pk = finite_difference_motion_peaks(kin.position.col(a), P.te);
      for (Index k = 0; k < model.samples(); ++k) raise(pk.current, model.current_peak_A(k, a), k);
      return pk;
    };
    av.twin_c1 = peaks(t1, v.c1);
    av.twin_c2 = peaks(t2, v.c2);
    av.model_c1 = peaks(v.c1, v.c1);
    av.model_c2 = peaks(v.c2, v.c2);
    av.violation_c1 = limit_violation(av.twin_c1, ax, P.te);
    av.violation_c2 = limit_violation(av.twin_c2, ax, P.te);
    const auto i1 = v.c1.current_setpoint_A.col(a).array(), i2 = v.c2.current_setpoint_A.col(a).array();
    av.current_setpoint_peak_c1_A = i1.abs().maxCoeff();
    av.current_setpoint_peak_c2_A = i2.abs().maxCoeff();
    Index row = 0;
    av.current_setpoint_max_diff_A = (i2 - i1).abs().maxCoeff(&row);
    av.current_setpoint_max_diff_row = row;
    av.current_setpoint_max_rel_diff =
        av.current_setpoint_peak_c1_A > 0 ? av.current_setpoint_max_diff_A / av.current_setpoint_peak_c1_A : 0.0;
    if (!av.violation_c2.empty()) {
      v.limits_held = false;
      // Where: the window whose commands produced the row (row r comes from command r - 1).
      const Index r = broken_peak(av.twin_c2, ax)->row;
      std::string where;
      for (std::size_t wi = 0; wi < res.windows.size(); ++wi) {
        const Window& w = res.windows[wi].window;
        if (r - 1 >= w.begin && r - 1 < w.end) where = fmt::format(" (window {}, {})", wi, window_kind_name(w.kind));
      }
      v.advice.push_back(fmt::format(
          "axis {}: {}{} with the schedule{}; narrow its range [{:g}, {:g}] towards C1's Kp {:g}, or lower the gain "
          "frequency f (a longer sinusoid, eq. 3), or lengthen the windows: a change dK of Kv over p samples adds "
          "about dK |e| (pi / (p Te))^2 / 2 of jerk, e the tracking error",
          ax.name, av.violation_c2, where, av.violation_c1.empty() ? "" : fmt::format(" (C1: {})", av.violation_c1),
          res.range[q].first, res.range[q].second, res.c1[q].kp));
    }
    v.axes.push_back(std::move(av));
  }
  return v;
}

Eigen::ArrayXd feed_move_row_weights(const core::Setpoints& sp, const core::ToolPath& program, double settle_s) {
  const Eigen::Index ns = sp.samples();
  if (ns == 0) throw core::Error("OGA: no setpoints");
  const Eigen::Index rows = ns + static_cast<Eigen::Index>(std::llround(settle_s / sp.period_s));
  Eigen::ArrayXd w = Eigen::ArrayXd::Zero(rows);
  for (Eigen::Index k = 0; k < rows; ++k) {
    const int mi = sp.move_index[std::min(k, ns - 1)];
    w[k] = mi >= 0 && !program.moves[static_cast<std::size_t>(mi)].rapid ? 1.0 : 0.0;
  }
  return w;
}

void set_range_of_moving_axes(const core::Setpoints& sp, const core::Machine& machine,
                              const std::pair<double, double>& all,
                              std::map<std::string, std::pair<double, double>>& range) {
  for (const char* n : {"X", "Y", "Z"}) {
    const int a = machine.axis_index(n[0] - 'X');
    if (a >= 0 && (sp.position.col(a).array() != sp.position(0, a)).any() && !range.count(n)) range[n] = all;
  }
}

}  // namespace vmsim::methods
