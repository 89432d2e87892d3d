#include "methods/feedplan_play.hpp"

#include "core/error.hpp"
#include "motion/smooth_path.hpp"
#include "drives/simulate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace vmsim::methods {

PlayedPlan play_plan(const PlanPlayer& player, const PathSamples& samples, const FeedPlan* plan) {
  if (!player.program || !player.machine) throw core::Error("play_plan: no program or machine");
  const core::Machine& machine = *player.machine;
  motion::InterpOptions io = player.interp;
  const motion::SmoothPath path = motion::smooth_path_for(*player.program, machine, io);
  if (plan && player.follow)
    io.feed_ceiling = feed_profile(*plan, path.length, player.to_path_s);
  else if (plan)
    io.feed_ceiling = feed_ceiling(*plan, player.to_path_s);
  PlayedPlan out;
  out.ceiling = io.feed_ceiling;
  out.interp =
      player.interpolate ? player.interpolate(io.feed_ceiling) : motion::interpolate(*player.program, machine, io);
  const core::Setpoints& sp = out.interp.setpoints;
  if (player.simulate) {
    out.actual = player.simulate(sp);
  } else if (player.servo.empty()) {
    drives::SimulateOptions so;
    so.settle_s = player.settle_s;
    out.actual = drives::simulate_axes(sp, machine, so).position;
  } else {
    out.actual = simulate_transfer_functions(sp, player.servo, player.settle_s);
  }
  // X Y Z of the command and of the simulated axes (axis space is the tool tip's on an xyz machine, up to the tool
  // length offset, a constant shift that leaves distances alone).
  const Eigen::Index ns = sp.samples(), na = out.actual.rows();
  Eigen::MatrixXd cmd = Eigen::MatrixXd::Zero(ns, 3), act = Eigen::MatrixXd::Zero(na, 3);
  for (std::size_t a = 0; a < machine.axes.size(); ++a) {
    const int pa = machine.axes[a].program_axis;
    if (pa > 2) continue;
    cmd.col(pa) = sp.position.col(static_cast<Eigen::Index>(a));
    act.col(pa) = out.actual.col(static_cast<Eigen::Index>(a));
  }
  out.contour = motion::contour_error(cmd, act);
  out.max_abs_mm = out.contour.max_abs_mm;

  // Each row's foot point as a plan arc length, and the largest error per plan sample.
  const Eigen::Index n = samples.size();
  out.sample_s.resize(na);
  out.per_sample.setZero(n);
  for (Eigen::Index k = 0; k < na; ++k) {
    const Eigen::Index i = std::clamp<Eigen::Index>(out.contour.foot_segment[k], 0, ns - 1);
    const Eigen::Index j = std::min<Eigen::Index>(i + 1, ns - 1);
    // The foot's place along its segment, from the projection of the actual point.
    const Eigen::Vector3d a = cmd.row(i).transpose(), b = cmd.row(j).transpose(), q = act.row(k).transpose();
    const double L2 = (b - a).squaredNorm();
    const double w = L2 > 0 ? std::clamp((q - a).dot(b - a) / L2, 0.0, 1.0) : 0.0;
    const double ps = sp.path_length_mm[i] + w * (sp.path_length_mm[j] - sp.path_length_mm[i]);
    const double s = player.to_sample_s ? player.to_sample_s(ps) : ps;
    out.sample_s[k] = s;
    const Eigen::Index idx =
        std::clamp<Eigen::Index>(static_cast<Eigen::Index>(std::llround(s / samples.ds)), 0, n - 1);
    out.per_sample[idx] = std::max(out.per_sample[idx], std::abs(out.contour.signed_mm[k]));
  }

  // Chord error per setpoint: the path's point halfway along the arc between two setpoints against the chord's middle.
  out.chord_error_mm.setZero(ns);
  for (Eigen::Index k = 0; k + 1 < ns; ++k) {
    const double sm = 0.5 * (sp.path_length_mm[k] + sp.path_length_mm[k + 1]);
    const core::Vec6 pm = path.point(sm);
    const Eigen::Vector3d mid = 0.5 * (cmd.row(k) + cmd.row(k + 1)).transpose();
    out.chord_error_mm[k] = (pm.head<3>() - mid).norm();
  }
  return out;
}

VerifiedPlan plan_feed_verified(const PathSamples& samples, const FeedPlanOptions& options, const PlanPlayer& player,
                                const VerifyOptions& verify) {
  const double eps0 = options.limits.contour_error_mm;
  if (!(verify.margin > 0 && verify.margin <= 1) || !(verify.reach_back_mm >= 0) || !(verify.reach_ahead_mm >= 0) ||
      verify.max_rounds < 1)
    throw core::Error("feed plan verification: margin in (0, 1], reaches >= 0, at least one round");
  const Eigen::Index n = samples.size();
  VerifiedPlan out;
  FeedPlanOptions opt = options;
  out.contour_scale = opt.contour_scale.size() == n ? opt.contour_scale : Eigen::ArrayXd::Ones(n);
  for (int round = 1; round <= verify.max_rounds; ++round) {
    opt.contour_scale = out.contour_scale;
    out.plan = plan_feed(samples, opt);
    out.played = play_plan(player, samples, &out.plan);
    out.rounds = round;
    out.simulated_peak_mm.push_back(out.played.max_abs_mm);
    out.model_time_s.push_back(out.plan.time_s);
    if (!(eps0 > 0) || out.played.max_abs_mm <= eps0) {
      out.holds = eps0 > 0;
      break;
    }
    // Stretches of samples over eps0: scale eps0 on and before each by margin * eps0 / its peak.
    Eigen::ArrayXd factor = Eigen::ArrayXd::Ones(n);
    const Eigen::ArrayXd& e = out.played.per_sample;
    for (Eigen::Index i = 0; i < n;) {
      if (!(e[i] > eps0)) {
        ++i;
        continue;
      }
      Eigen::Index j = i;
      double peak = 0.0;
      while (j < n && e[j] > eps0) peak = std::max(peak, e[j]), ++j;
      const double f = verify.margin * eps0 / peak;
      const double s0 = samples.s[i] - verify.reach_back_mm, s1 = samples.s[j - 1] + verify.reach_ahead_mm;
      for (Eigen::Index k = 0; k < n; ++k)
        if (samples.s[k] >= s0 && samples.s[k] <= s1) factor[k] = std::min(factor[k], f);
      i = j;
    }
    if ((factor == 1.0).all()) break;  // the excess is not on any sample (cannot be attributed): stop
    out.contour_scale *= factor;
  }
  return out;
}

}  // namespace vmsim::methods
