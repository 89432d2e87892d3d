#include "sysid/excite_axis.hpp"

#include "core/error.hpp"
#include "core/units.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/simulate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace vmsim::sysid {

AxisExcitation excitation_for_axis(const core::MachineAxis& ax, const AxisExcitationOptions& options) {
  const bool rotary = ax.kind == core::AxisKind::Rotary;
  const double unit = rotary ? core::units::kDegToRad : 1.0;  // file units (mm, deg) to axis units, for messages
  ExcitationSpec s;
  s.signal = options.signal;
  s.period_s = options.period_s;
  s.switch_samples =
      options.switch_samples ? *options.switch_samples : switch_samples_for_bandwidth(options.bandwidth_hz, s.period_s);
  s.bits = options.bits ? *options.bits
                        : bits_for_resolution(options.resolution_hz, s.switch_samples * s.period_s,
                                              s.signal == ExcitationSignal::InverseM);
  s.amplitude = options.amplitude;
  s.velocity = options.velocity;
  s.periods = options.periods;
  // Length of the ramp the signal rides on, to centre it in the travel (eq. 13: a <= travel / 2).
  const Eigen::VectorXd probe = excitation_setpoints(s);
  const double run = probe[probe.size() - 1] - probe[0];
  const bool limited = !ax.continuous && ax.travel_max > ax.travel_min;
  s.start = options.start ? *options.start : (limited ? 0.5 * (ax.travel_min + ax.travel_max) - 0.5 * run : 0.0);
  AxisExcitation e{s, excitation_setpoints(s)};
  const Eigen::VectorXd& x = e.setpoints;
  if (limited && (x.minCoeff() < ax.travel_min - 1e-9 || x.maxCoeff() > ax.travel_max + 1e-9))
    throw core::Error(
        fmt::format("the excitation spans {:.4f} .. {:.4f} {}, outside axis {}'s travel {:.4f} .. {:.4f} "
                    "(lower --feed, --periods or --amplitude, or move --start)",
                    x.minCoeff() / unit, x.maxCoeff() / unit, rotary ? "deg" : "mm", ax.name, ax.travel_min / unit,
                    ax.travel_max / unit));
  return e;
}

PositionTrace simulate_excitation(const core::MachineAxis& ax, const AxisExcitation& excitation,
                                  const std::string& machine_file) {
  if (!ax.drive)
    throw core::Error(core::located(machine_file, 0, fmt::format("axis {} has no [axes.drive] to simulate", ax.name)));
  const ExcitationSpec& s = excitation.spec;
  const Eigen::VectorXd& x = excitation.setpoints;
  drives::CascadeAxis drive(*ax.drive, s.period_s, ax.kind);
  drive.reset(x[0]);
  const Eigen::Index rows = x.size() + static_cast<Eigen::Index>(std::lround(0.1 / s.period_s));
  const Eigen::VectorXd y = drives::simulate_axis(drive, x, s.period_s, rows);
  PositionTrace tr;
  tr.period_s = s.period_s;
  tr.axes = {ax.name};
  tr.rotary = {ax.kind == core::AxisKind::Rotary};
  tr.t_s = Eigen::ArrayXd::LinSpaced(rows, 0.0, (rows - 1) * s.period_s);
  tr.command.resize(rows, 1);
  tr.actual.resize(rows, 1);
  for (Eigen::Index k = 0; k < rows; ++k) tr.command(k, 0) = x[std::min(k, x.size() - 1)];
  tr.actual.col(0) = y;
  return tr;
}

}  // namespace vmsim::sysid
