// vmsim excite AXIS --machine M --out FILE: the predictive-compensation paper's identification signal (inverse M-sequence or PRBS, eq. 8-15)
// as a G-code program or a setpoint CSV; with --simulate, also the trace the machine file's drive gives for it.
#include "app/commands_sysid.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/machine.hpp"
#include "core/units.hpp"
#include "drives/cascade_axis.hpp"
#include "sysid/excite.hpp"
#include "sysid/position_trace.hpp"
#include "drives/simulate.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>

namespace vmsim::app {

int run_excite(const ExciteArgs& args) {
  const std::string ext = args.out.extension().string();
  if (ext != ".ngc" && ext != ".nc" && ext != ".csv")
    throw core::Error(fmt::format("--out {}: expected a .ngc/.nc (G-code) or .csv (setpoints) file", args.out.string()));
  if (args.signal != "inverse-m" && args.signal != "prbs")
    throw core::Error(fmt::format("--signal '{}': expected inverse-m or prbs", args.signal));
  if (!(args.period_ms > 0.0)) throw core::Error("--period-ms must be positive");
  const core::Machine machine = core::load_machine(args.machine);
  int ai = -1;
  for (std::size_t i = 0; i < machine.axes.size(); ++i)
    if (machine.axes[i].name == args.axis) ai = static_cast<int>(i);
  if (ai < 0) throw core::Error(core::located(args.machine.string(), 0, fmt::format("no axis {}", args.axis)));
  const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(ai)];
  const bool rotary = ax.kind == core::AxisKind::Rotary;
  const double unit = rotary ? core::units::kDegToRad : 1.0;  // file units (mm, deg) to axis units

  sysid::ExcitationSpec s;
  s.signal = args.signal == "prbs" ? sysid::ExcitationSignal::Prbs : sysid::ExcitationSignal::InverseM;
  s.period_s = args.period_ms * 1e-3;
  s.switch_samples = args.td_ms ? static_cast<int>(std::lround(*args.td_ms / args.period_ms))
                                : sysid::switch_samples_for_bandwidth(args.bandwidth_hz, s.period_s);
  if (s.switch_samples < 1) throw core::Error(fmt::format("--td-ms {}: Td must be at least one period Te", *args.td_ms));
  s.bits = args.bits ? *args.bits
                     : sysid::bits_for_resolution(args.resolution_hz, s.switch_samples * s.period_s,
                                                   s.signal == sysid::ExcitationSignal::InverseM);
  s.amplitude = args.amplitude * unit;
  s.velocity = args.feed / 60.0 * unit;
  s.periods = args.periods;
  // Length of the ramp the signal rides on, to centre it in the travel (eq. 13: a <= travel / 2).
  const Eigen::VectorXd probe = sysid::excitation_setpoints(s);
  const double run = probe[probe.size() - 1] - probe[0];
  const bool limited = !ax.continuous && ax.travel_max > ax.travel_min;
  s.start = args.start ? *args.start * unit : (limited ? 0.5 * (ax.travel_min + ax.travel_max) - 0.5 * run : 0.0);
  const Eigen::VectorXd x = sysid::excitation_setpoints(s);
  if (limited && (x.minCoeff() < ax.travel_min - 1e-9 || x.maxCoeff() > ax.travel_max + 1e-9))
    throw core::Error(fmt::format("the excitation spans {:.4f} .. {:.4f} {}, outside axis {}'s travel {:.4f} .. {:.4f} "
                                  "(lower --feed, --periods or --amplitude, or move --start)",
                                  x.minCoeff() / unit, x.maxCoeff() / unit, rotary ? "deg" : "mm", ax.name,
                                  ax.travel_min / unit, ax.travel_max / unit));

  const double td = s.switch_samples * s.period_s;
  const double sig_period = (s.signal == sysid::ExcitationSignal::InverseM ? 2.0 : 1.0) * (std::ldexp(1.0, s.bits) - 1.0) * td;
  const std::vector<std::string> header = {
      fmt::format("vmsim excite: {} on axis {} of {}", args.signal, ax.name, machine.name),
      fmt::format("the predictive-compensation paper eq. 8-15: n = {} bits, Td = {} ms ({} x Te), amplitude {} {}, signal period {:.4f} s, {} "
                  "periods, bandwidth 0.433/Td = {:.1f} Hz",
                  s.bits, td * 1e3, s.switch_samples, args.amplitude, rotary ? "deg" : "mm", sig_period, s.periods,
                  0.433 / td),
      fmt::format("on a constant velocity of {} {}/min from {:.4f} {}", args.feed, rotary ? "deg" : "mm",
                  s.start / unit, rotary ? "deg" : "mm")};
  if (ext == ".csv") {
    std::string out;
    for (const auto& h : header) out += "# " + h + "\n";
    out += fmt::format("t_s,{}_{}\n", ax.name, rotary ? "deg" : "mm");
    for (Eigen::Index k = 0; k < x.size(); ++k) out += fmt::format("{:.6f},{:.10f}\n", k * s.period_s, x[k] / unit);
    core::write_file_atomic(args.out, out);
  } else {
    core::write_file_atomic(args.out, sysid::excitation_gcode(s, ax.name, rotary, header));
  }
  std::printf("%s\n%s\n%s\nwrote %s (%lld setpoints, %.3f s)\n", header[0].c_str(), header[1].c_str(), header[2].c_str(),
              args.out.string().c_str(), static_cast<long long>(x.size()), (x.size() - 1) * s.period_s);

  if (args.simulate) {
    // The setpoints themselves (not the NC's interpolation of the G-code) through the axis's cascade.
    if (!ax.drive)
      throw core::Error(core::located(args.machine.string(), 0, fmt::format("axis {} has no [axes.drive] to simulate", ax.name)));
    drives::CascadeAxis drive(*ax.drive, s.period_s, ax.kind);
    drive.reset(x[0]);
    const Eigen::Index rows = x.size() + static_cast<Eigen::Index>(std::lround(0.1 / s.period_s));
    const Eigen::VectorXd y = drives::simulate_axis(drive, x, s.period_s, rows);
    sysid::PositionTrace tr;
    tr.period_s = s.period_s;
    tr.axes = {ax.name};
    tr.rotary = {rotary};
    tr.t_s = Eigen::ArrayXd::LinSpaced(rows, 0.0, (rows - 1) * s.period_s);
    tr.command.resize(rows, 1);
    tr.actual.resize(rows, 1);
    for (Eigen::Index k = 0; k < rows; ++k) tr.command(k, 0) = x[std::min(k, x.size() - 1)];
    tr.actual.col(0) = y;
    std::vector<std::string> c = header;
    c.push_back("simulated on the cascade drive of " + args.machine.filename().string() + " [axes.drive]");
    sysid::write_position_trace_csv(*args.simulate, tr, c);
    std::printf("wrote %s (position trace, %lld samples)\n", args.simulate->string().c_str(), static_cast<long long>(rows));
  }
  return 0;
}

}  // namespace vmsim::app
