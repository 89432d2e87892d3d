#pragma once
// signals.csv: the drive signals of a run, compact enough to chart later (`vmsim render DIR`) whatever the run's
// length. The plane-cylinder reference job has ~4 M samples per signal; the file keeps, for consecutive bins of
// samples, each signal's minimum and maximum over the bin, so that a peak of one sample survives the decimation to
// ~10 000 bins (a chart drawn from min and max per bin looks like the full-rate one at any width up to the number
// of bins). `vmsim run` and `vmsim motion` write it; `vmsim render` reads it.
//
// Format (CSV, '#' lines first):
//   # vmsim signals 1: per-bin minimum and maximum of each signal (columns NAME.min, NAME.max) ...
//   # job=NAME
//   # period_s=0.001          sample period Te
//   # samples=N               samples before binning
//   # bin_samples=K           samples per bin (the last bin may hold fewer)
//   # axes=X:mm,Z:mm          the machine axes that move (their signals are in the file), with their unit
//   # held_axes=Y,A,C         the axes that do not move (not in the file)
//   # limit NAME=VALUE        |signal| limit of the machine file, e.g. limit X_velocity_mm_per_s=500
//   t_s.min,t_s.max,X_setpoint_mm.min,X_setpoint_mm.max,...
//   one row per bin; "nan" where a signal is undefined over the whole bin (contour error on rapids)
//
// Signals (units in the names; axis unit U is mm, or deg for rotary axes):
//   t_s                                      time of the sample
//   A_setpoint_U, A_actual_U                 axis position: interpolator setpoint, drive's actual position
//   A_tracking_error_U                       setpoint - actual
//   A_velocity_setpoint_U_per_s, A_velocity_actual_U_per_s         (setpoints: backward differences, as the
//   A_acceleration_setpoint_U_per_s2, A_acceleration_actual_U_per_s2 drives receive them; actual: the drive model)
//   A_jerk_setpoint_U_per_s3, A_jerk_actual_U_per_s3
//   A_current_A                              motor current, mean over each Te (signed)
//   A_current_peak_A                         largest |current| within each Te
//   feed_programmed_mm_per_min               the programmed feed x the feed scale, on feed moves (nan on rapids)
//   path_speed_setpoint_mm_per_min           speed of the setpoints along the (smoothed) path
//   path_speed_actual_mm_per_min             speed of the actual tool tip
//   contour_error_mm                         signed contour error on cutting moves (nan on rapids)
//   cutting_path_mm                          length of the commanded tool-tip path along cutting moves so far
//   cutting                                  1 on cutting (feed) moves, 0 on rapids
//   limits: A_velocity_U_per_s, A_acceleration_U_per_s2, A_jerk_U_per_s3 (setpoint limits), A_current_A (drive)
#include "motion/contour.hpp"
#include "core/job.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"
#include "drives/simulate.hpp"
#include "motion/kinematics.hpp"

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::sim {

struct BinnedSignals {
  std::string job;
  double period_s = 1e-3;
  Eigen::Index samples = 0, bin_samples = 1;
  std::vector<std::pair<std::string, std::string>> axes;  // moving axes: (name, unit)
  std::vector<std::string> held_axes;
  std::map<std::string, double> limits;
  std::vector<std::string> names;
  Eigen::ArrayXXd min, max;  // bins x names

  Eigen::Index bins() const { return min.rows(); }
  // Column of `name`, or -1.
  int find(const std::string& name) const;
  bool has(const std::string& name) const { return find(name) >= 0; }
  std::optional<double> limit(const std::string& name) const;
};

// The signals of a run through the drives binned as the drives' response comes, in blocks of rows (issue 21: a long
// program's response need not be held whole): add() each block in order, add_contour() once the contour error is
// known, then finish(). Each column's values fold into their bins in row order, so the bins do not depend on the
// blocks. The setpoints (positions, path speed, move indices) must stay alive until the last add(); the program and
// the move indices until add_contour().
class SignalBinner {
 public:
  // rows: the response's rows (setpoints, then the settling rows). feed_scale: the override the setpoints were
  // interpolated with. Throws core::Error for a run without samples.
  SignalBinner(const core::Job& job, const core::ToolPath& program, const core::Setpoints& setpoints, Eigen::Index rows,
               double feed_scale = 1.0, Eigen::Index max_bins = 10000);
  ~SignalBinner();
  SignalBinner(SignalBinner&&) noexcept = default;
  // Response rows [k0, k0 + block.samples()); k0 must follow the previous block. Throws core::Error otherwise.
  void add(Eigen::Index k0, const drives::AxisResponse& block);
  // The same with the block's tool tips already known (rows of the block, 3 columns): the actual one (forward
  // kinematics of the response) and the commanded one (of the setpoint each row holds); bit for bit what add()
  // computes itself. Throws core::Error also when their shapes are not the block's.
  void add(Eigen::Index k0, const drives::AxisResponse& block, const Eigen::Ref<const Eigen::MatrixXd>& actual_tip_mm,
           const Eigen::Ref<const Eigen::MatrixXd>& command_tip_mm);
  // The contour error of every row. Throws core::Error when its length is not the response's.
  void add_contour(const motion::ContourError& contour);
  // Throws core::Error when rows are missing.
  BinnedSignals finish();

 private:
  struct Column {
    Eigen::ArrayXd lo, hi;
  };
  struct AxisColumns {
    Eigen::Index axis;
    double scale;
    int first;  // its eleven columns, from the setpoint's
  };
  int column(const std::string& name);
  void check_block(Eigen::Index k0, Eigen::Index rows) const;  // k0 follows the last block, the rows fit
  // Column col's values v[0, r1 - r0) of rows [r0, r1) of a block starting at row k0 (times f when Scaled) into its
  // bins, with the bits a fold in row order gives (signals.cpp says how).
  template <bool Scaled>
  void fold_column(int col, Eigen::Index k0, Eigen::Index r0, Eigen::Index r1, const double* v, double f = 1.0);
  void add_rows(Eigen::Index k0, const drives::AxisResponse& block, Eigen::Index r0, Eigen::Index r1,
                const Eigen::Ref<const Eigen::MatrixXd>& actual_tip_mm,
                const Eigen::Ref<const Eigen::MatrixXd>& command_tip_mm);
  int move_of(Eigen::Index k) const;
  bool cutting(Eigen::Index k) const;
  double tlo(Eigen::Index k) const;

  const core::Job* job_;
  const core::ToolPath* program_;
  const core::Setpoints* sp_;
  Eigen::Index n_, ns_, bs_ = 1, bins_ = 0, next_ = 0;
  double te_ = 1e-3, feed_scale_ = 1.0;
  std::unique_ptr<motion::Kinematics> kin_;
  BinnedSignals out_;
  std::vector<Column> columns_;
  std::vector<AxisColumns> axes_;
  int c_feed_ = 0, c_speed_ = 0, c_speed_actual_ = 0, c_contour_ = 0, c_path_ = 0, c_cutting_ = 0;
  Eigen::Vector3d prev_actual_ = Eigen::Vector3d::Zero(), prev_command_ = Eigen::Vector3d::Zero();
  double cutting_path_ = 0;
  std::vector<double> feed_, speed_, speed_actual_, path_, cutting_;  // add_rows' per-row values
  std::vector<double> xs_;                                            // add_rows: an axis' setpoints k-3..k
  std::vector<double> ts_;  // add_rows: the rows' times; add_contour: a chunk of the contour error's values
  std::array<std::vector<double>, 5> sv_;  // add_rows: an axis' setpoint, tracking error and differences per row
};

// The signals of one run through the drives, binned on the fly (no full-rate copy of the signals is made).
// feed_scale: the override the setpoints were interpolated with (it scales the programmed feeds).
BinnedSignals motion_signals(const core::Job& job, const core::ToolPath& program, const core::Setpoints& setpoints,
                             const drives::AxisResponse& response, const motion::ContourError& contour,
                             double feed_scale = 1.0, Eigen::Index max_bins = 10000);

// Written atomically. Throws core::Error on I/O errors.
void write_signals(const std::filesystem::path& file, const BinnedSignals& signals);
// Throws core::Error naming the file, the line and what was expected.
BinnedSignals read_signals(const std::filesystem::path& file);

}  // namespace vmsim::sim
