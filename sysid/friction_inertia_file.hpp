#pragma once
// Friction and inertia identification (sysid/friction_inertia.hpp) between machine files: the motor data and the
// gravity model taken from a machine file's axis, the result written back as the identified keys of its
// [axes.drive] table (what `vmsim identify-friction` writes as drive_identified.toml), and the points of the
// friction law (the feed-drive simulation paper Fig. 3) as CSV.
#include "core/machine.hpp"
#include "sysid/friction_inertia.hpp"

#include <optional>
#include <string>

namespace vmsim::sysid {

// The inverse of gravity_model_name (sysid/friction_inertia.hpp): nullopt for anything else.
std::optional<GravityModel> parse_gravity_model(const std::string& name);

// The torque constant, the screw lead or gear ratio and, when `gravity` is Auto, the gravity model of `axis`
// (a machine file's [axes.drive]) for identifying it from `trace`. Throws core::Error naming `machine_file` when
// the axis has no [axes.drive] table, or when its kind (linear, rotary) is not the trace's (mm, deg).
IdentifyOptions identify_options_for_axis(const core::MachineAxis& axis, const std::string& machine_file,
                                          const AxisTrace& trace, GravityModel gravity);

// Whether the identified gravity term belongs in the machine file: a model was fitted, and it was asked for (a
// given model, or the machine file's) or it stands out of the noise (more than 3 standard errors). A gravity
// chosen by the fit alone and not distinguishable from zero is a horizontal axis: writing the noise as a gravity
// torque would model a load the axis does not carry.
bool gravity_is_written(const IdentifiedDrive& d, bool gravity_model_given);

// drive_identified.toml: a comment header naming `trace_name` and the fit, then [axes.drive] with the motor data
// of `options` and the identified inertia, friction and gravity keys (parts/README.md). `rotary`: a gear in deg per
// motor revolution, else a screw lead in mm.
std::string identified_drive_toml(const IdentifiedDrive& d, const IdentifyOptions& options, bool rotary,
                                  const std::string& trace_name, bool write_gravity);

// friction_fit.csv: one row per constant-velocity stretch (velocity in mm/s or deg/s, measured and fitted mean
// current, samples, time span).
std::string friction_points_csv(const IdentifiedDrive& d, bool rotary);

}  // namespace vmsim::sysid
