#pragma once
// Several CascadeAxis drives advanced together, one Te at a time, with results bit for bit those of
// CascadeAxis::step on each axis alone (issue 21: the drives were the largest part of a long run's CPU).
//
// Why it is faster: one current period of one axis is a chain of dependent floating-point operations (PI -> ZOH
// plant -> friction), so one axis alone keeps the core waiting on latencies. Here the loop body steps every axis of
// the batch in turn: their chains are independent and the out-of-order core overlaps them. Each axis still sees the
// same operations in the same order (no reassociation, no fused multiply-add: the generic build has none), hence the
// same bits. An axis whose period left its whole state unchanged (at rest, e.g. the rotary axes of a three-axis
// program) and whose next period has the same inputs bit for bit (the loop's velocity command and current
// feedforward) is not stepped again: the model is deterministic, so that period's result is the last one's.
#include "drives/cascade_axis.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

namespace vmsim::drives {

// One axis of a CascadeBatch: its constants (copied from the CascadeAxis) and its state, side by side for locality.
struct CascadeLane {
  double kpv, kiv, kpc, kic, current_limit, voltage_limit;
  double phi[3][3], gam_u[3], gam_t[3], stuck_a, stuck_b;
  double kt, breakaway, stick_window, coulomb, stribeck_static, stribeck_velocity, gravity_Nm, gravity_offset;
  double r, inv_r, ff_current_per_accel, te;
  int gravity;  // 0 none, 1 constant, 2 tilting (core::DriveParams::Gravity)
  bool friction;
  // State (CascadeAxis' i_, w_, x_, ic_, iv_, iset_, u_).
  double i, w, x, ic, iv, iset, u;
  // This period's loop inputs and sums.
  double w_cmd, i_ff, i_sum, i_peak, w_start;
  // The last period: its inputs and result, and whether it left the state unchanged (then the same inputs give
  // the same period again).
  double last_w_cmd, last_i_ff;
  bool fixed;
  AxisSample last;
};

struct CascadePack;

// One lane's side of CascadeBatch::run_rows, as simulate_axes' rows define it (drives/simulate.hpp): the NC's setpoint
// and gain columns for the lane's axis, its response columns, and what the NC carries from one row to the next.
struct CascadeRowLane {
  const double* setpoints = nullptr;  // the axis' setpoint column (n_set rows)
  const double *kv = nullptr,
               *kf = nullptr;  // its gain schedule columns (setpoint rows; NaN: the drive's own), or null
  // position, velocity, acceleration, jerk, current_A, current_mean_A, current_peak_A, current_setpoint_A; entry 0
  // of each is row `base` of run_rows.
  double* out[8] = {};
  AxisSample s;                       // the sample at the next row's instant
  double prev_x = 0.0, prev_v = 0.0;  // the NC's previous setpoint and velocity
  double prev_acc = 0.0;              // the previous row's acceleration (the jerk's backward difference)
};

// The kernels CascadeBatch is compiled into, widest last; each gives the same bits.
enum class CascadeBatchKernel { Generic, Avx2, Avx512 };
// Whether this processor runs `kernel`.
bool cascade_batch_supports(CascadeBatchKernel kernel);
// Tests: the widest kernel to use (default: Avx512, i.e. the widest the processor has), so that every kernel the
// processor runs can be held to the same bits.
CascadeBatchKernel& cascade_batch_kernel_limit();

class CascadeBatch {
 public:
  static constexpr int kMaxLanes = 8;

  // Whether two axes can share a batch: the same number of current periods per Te and per velocity period.
  static bool compatible(const CascadeAxis& a, const CascadeAxis& b);

  // Takes the axes' state; each axis stays owned by the caller, must outlive the batch and must not be stepped
  // while the batch runs (store() hands the state back). trace: keep each period's current-loop samples (trace()).
  // Throws core::Error for no axis, more than kMaxLanes, or axes that are not compatible().
  CascadeBatch(const std::vector<CascadeAxis*>& axes, bool trace);
  ~CascadeBatch();
  CascadeBatch(CascadeBatch&&) noexcept;

  int lanes() const { return static_cast<int>(axes_.size()); }
  // One Te for every lane: samples[l] is what axes[l]->step(commands[l]) returns.
  void step(const AxisCommand* commands, AxisSample* samples);
  // After step() with trace on: lane l's inner_steps() current-loop samples of that period (as
  // CascadeAxis::step(command, trace) writes them).
  const InnerSample* trace(int lane) const;
  // Rows [k0, k1) of a run of `rows` rows with n_set setpoints (the last one held beyond), NC period te: row k from
  // lanes[l].s, then (unless k + 1 == rows) the command of setpoint row min(k, n_set - 1) and one Te, whose sample
  // is row k + 1 (written when k + 1 < k1, and left in lanes[l].s for the next call). Bit for bit what step() gives
  // one Te at a time, but the lanes' state stays in the vectors from one Te to the next. No trace (step() keeps one).
  void run_rows(CascadeRowLane* lanes, long long k0, long long k1, long long base, long long n_set, long long rows,
                double te);
  // Lane periods not stepped because they repeat the last one (a measure of the shortcut, for tests and benches).
  long long skipped_periods() const { return skipped_; }
  // Writes the lanes' state back into the axes: CascadeAxis::step then goes on from where the batch stopped.
  void store() const;

 private:
  void pack(const int* active, int m);
  template <bool kTrace>
  void advance(const AxisCommand* commands, AxisSample* samples);

  std::vector<CascadeAxis*> axes_;
  std::vector<CascadeLane> lanes_;
  int per_te_ = 1, per_velocity_ = 1;
  bool trace_ = false;
  long long skipped_ = 0;
  std::vector<InnerSample> trace_buf_;    // lanes x per_te_
  std::vector<InnerSample> trace_slots_;  // kMaxLanes x per_te_, as the pack's slots write it
  std::unique_ptr<CascadePack> pack_;     // the active lanes as vectors (cascade_batch.cpp)
  int packed_[kMaxLanes] = {}, packed_m_ = -1;
};

}  // namespace vmsim::drives
