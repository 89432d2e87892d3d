// vmsim excite AXIS --machine M --out FILE: the predictive-compensation paper's identification signal (inverse
// M-sequence or PRBS, eq. 8-15; sysid::excitation_for_axis) as a G-code program or a setpoint CSV; with --simulate,
// also the trace the machine file's drive gives for it (sysid::simulate_excitation).
#include "app/commands_sysid.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/machine.hpp"
#include "core/units.hpp"
#include "sysid/excite.hpp"
#include "sysid/excite_axis.hpp"
#include "sysid/position_trace.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace vmsim::app {

namespace {

// The options in axis units (mm, rad); `unit` converts the command line's mm or deg.
sysid::AxisExcitationOptions excitation_options(const ExciteArgs& args, double unit) {
  sysid::AxisExcitationOptions o;
  o.signal = args.signal == "prbs" ? sysid::ExcitationSignal::Prbs : sysid::ExcitationSignal::InverseM;
  o.period_s = args.period_ms * 1e-3;
  if (args.td_ms) {
    o.switch_samples = static_cast<int>(std::lround(*args.td_ms / args.period_ms));
    if (*o.switch_samples < 1)
      throw core::Error(fmt::format("--td-ms {}: Td must be at least one period Te", *args.td_ms));
  }
  o.bandwidth_hz = args.bandwidth_hz;
  o.bits = args.bits;
  o.resolution_hz = args.resolution_hz;
  o.amplitude = args.amplitude * unit;
  o.velocity = args.feed / 60.0 * unit;
  o.periods = args.periods;
  if (args.start) o.start = *args.start * unit;
  return o;
}

// The comment lines of both files: what the signal is, in the command line's units.
std::vector<std::string> header_lines(const ExciteArgs& args, const core::Machine& machine, const core::MachineAxis& ax,
                                      const sysid::ExcitationSpec& s, double unit) {
  const bool rotary = ax.kind == core::AxisKind::Rotary;
  const double td = s.switch_samples * s.period_s;
  const double sig_period =
      (s.signal == sysid::ExcitationSignal::InverseM ? 2.0 : 1.0) * (std::ldexp(1.0, s.bits) - 1.0) * td;
  return {fmt::format("vmsim excite: {} on axis {} of {}", args.signal, ax.name, machine.name),
          fmt::format("the predictive-compensation paper eq. 8-15: n = {} bits, Td = {} ms ({} x Te), amplitude {} {}, "
                      "signal period {:.4f} s, {} periods, bandwidth 0.433/Td = {:.1f} Hz",
                      s.bits, td * 1e3, s.switch_samples, args.amplitude, rotary ? "deg" : "mm", sig_period, s.periods,
                      0.433 / td),
          fmt::format("on a constant velocity of {} {}/min from {:.4f} {}", args.feed, rotary ? "deg" : "mm",
                      s.start / unit, rotary ? "deg" : "mm")};
}

std::string setpoints_csv(const std::vector<std::string>& header, const core::MachineAxis& ax,
                          const sysid::AxisExcitation& e, double unit) {
  const bool rotary = ax.kind == core::AxisKind::Rotary;
  std::string out;
  for (const auto& h : header) out += "# " + h + "\n";
  out += fmt::format("t_s,{}_{}\n", ax.name, rotary ? "deg" : "mm");
  for (Eigen::Index k = 0; k < e.setpoints.size(); ++k)
    out += fmt::format("{:.6f},{:.10f}\n", k * e.spec.period_s, e.setpoints[k] / unit);
  return out;
}

}  // namespace

int run_excite(const ExciteArgs& args) {
  const std::string ext = args.out.extension().string();
  if (ext != ".ngc" && ext != ".nc" && ext != ".csv")
    throw core::Error(
        fmt::format("--out {}: expected a .ngc/.nc (G-code) or .csv (setpoints) file", args.out.string()));
  if (args.signal != "inverse-m" && args.signal != "prbs")
    throw core::Error(fmt::format("--signal '{}': expected inverse-m or prbs", args.signal));
  if (!(args.period_ms > 0.0)) throw core::Error("--period-ms must be positive");
  const core::Machine machine = core::load_machine(args.machine);
  const auto it = std::find_if(machine.axes.begin(), machine.axes.end(),
                               [&](const core::MachineAxis& a) { return a.name == args.axis; });
  if (it == machine.axes.end())
    throw core::Error(core::located(args.machine.string(), 0, fmt::format("no axis {}", args.axis)));
  const core::MachineAxis& ax = *it;
  const bool rotary = ax.kind == core::AxisKind::Rotary;
  const double unit = rotary ? core::units::kDegToRad : 1.0;  // file units (mm, deg) to axis units

  const sysid::AxisExcitation e = sysid::excitation_for_axis(ax, excitation_options(args, unit));
  const std::vector<std::string> header = header_lines(args, machine, ax, e.spec, unit);
  if (ext == ".csv")
    core::write_file_atomic(args.out, setpoints_csv(header, ax, e, unit));
  else
    core::write_file_atomic(args.out, sysid::excitation_gcode(e.spec, ax.name, rotary, header));
  const Eigen::VectorXd& x = e.setpoints;
  std::printf("%s\n%s\n%s\nwrote %s (%lld setpoints, %.3f s)\n", header[0].c_str(), header[1].c_str(),
              header[2].c_str(), args.out.string().c_str(), static_cast<long long>(x.size()),
              (x.size() - 1) * e.spec.period_s);

  if (args.simulate) {
    sysid::PositionTrace tr = sysid::simulate_excitation(ax, e, args.machine.string());
    std::vector<std::string> c = header;
    c.push_back("simulated on the cascade drive of " + args.machine.filename().string() + " [axes.drive]");
    sysid::write_position_trace_csv(*args.simulate, tr, c);
    std::printf("wrote %s (position trace, %lld samples)\n", args.simulate->string().c_str(),
                static_cast<long long>(tr.t_s.size()));
  }
  return 0;
}

}  // namespace vmsim::app
