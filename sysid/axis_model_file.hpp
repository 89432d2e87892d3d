#pragma once
// The identified-model file (TOML) that `vmsim identify` writes and a job's [job] axis_models reads: one discrete
// transfer function per axis (the predictive-compensation paper eq. 5), keys documented in parts/README.md ("Identified
// axis models").
#include "drives/discrete_tf.hpp"
#include "sysid/sysid.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::sysid {

struct IdentifiedAxis {
  std::string name;  // machine axis: X Y Z A B C
  ModelStructure structure = ModelStructure::Oe;
  drives::DiscreteTf tf;              // G from command to encoder position
  Eigen::VectorXd c;                  // ARMAX noise numerator (kept for the record; not used to simulate)
  std::optional<double> fit_percent;  // validation figures, for the record
  std::optional<double> tracking_fit_percent;
};

struct AxisModelFile {
  std::string source_file;
  double period_s = 1e-3;  // Te the models were identified at
  std::string trace;       // the trace they came from (informational)
  std::vector<IdentifiedAxis> axes;
  const IdentifiedAxis* find(const std::string& axis) const;
};

// Throws core::Error naming the file, line and key for unknown keys, wrong types, orders out of range (nk >= 1,
// nb >= 1), non-finite or unstable coefficients (a pole of A on or outside the unit circle), duplicate axes.
AxisModelFile load_axis_models(const std::filesystem::path& path);
// Written atomically; coefficients with 17 significant digits so a round trip is exact.
void save_axis_models(const std::filesystem::path& path, const AxisModelFile& models,
                      const std::vector<std::string>& comment_lines);

}  // namespace vmsim::sysid
