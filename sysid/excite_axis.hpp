#pragma once
// An identification experiment on one machine axis (the predictive-compensation paper section 2.3): the
// excitation of sysid/excite.hpp sized for the axis (Td from its bandwidth, the register length from the frequency
// resolution, the signal centred in its travel) and, for trying it out before a machine is at hand, the trace the
// axis's cascade drive (drives/cascade_axis) gives for it.
#include "core/machine.hpp"
#include "sysid/excite.hpp"
#include "sysid/position_trace.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>

namespace vmsim::sysid {

struct AxisExcitationOptions {
  ExcitationSignal signal = ExcitationSignal::InverseM;
  std::optional<int> switch_samples;  // Td / Te; default: the bandwidth's (eq. 14-15)
  double bandwidth_hz = 100.0;        // the axis bandwidth the signal must cover
  std::optional<int> bits;            // register length n; default: the resolution's (eq. 11-12)
  double resolution_hz = 1.0;         // frequency resolution 1 / signal period
  double amplitude = 0.05;            // axis units (mm or rad)
  double velocity = 0.0;              // the constant velocity the signal rides on, axis units/s
  int periods = 4;
  std::optional<double> start;  // axis units; default: the signal's ramp centred in the travel
  double period_s = 1e-3;       // Te
};

struct AxisExcitation {
  ExcitationSpec spec;
  Eigen::VectorXd setpoints;  // every Te, axis units
};

// Throws core::Error when the setpoints leave the axis's travel (a continuous or unlimited axis has none), or for
// parameters excitation_setpoints refuses.
AxisExcitation excitation_for_axis(const core::MachineAxis& axis, const AxisExcitationOptions& options);

// The setpoints themselves (not the NC's interpolation of a program) through the axis's cascade drive, from rest at
// the first setpoint to 0.1 s past the last (held): command and encoder position every Te. Throws core::Error
// naming `machine_file` when the axis has no [axes.drive].
PositionTrace simulate_excitation(const core::MachineAxis& axis, const AxisExcitation& excitation,
                                  const std::string& machine_file);

}  // namespace vmsim::sysid
