#pragma once
// The drives tests' reference for the batched cascade (drives/cascade_batch): each axis alone through
// CascadeAxis::step (drives/cascade_axis.cpp), rows and commands as simulate_axes documents them (drives/simulate.hpp).
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/cascade_batch.hpp"
#include "drives/simulate.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <vector>

namespace vmsim::drives::test {

// The batch's kernels this processor runs (the generic one always), for the tests to hold each to the reference.
inline std::vector<CascadeBatchKernel> cascade_batch_kernels() {
  std::vector<CascadeBatchKernel> out;
  for (CascadeBatchKernel k : {CascadeBatchKernel::Avx512, CascadeBatchKernel::Avx2, CascadeBatchKernel::Generic})
    if (cascade_batch_supports(k)) out.push_back(k);
  return out;
}

// The kernel's name for a failure message.
inline const char* cascade_batch_kernel_name(CascadeBatchKernel k) {
  return k == CascadeBatchKernel::Generic ? "generic" : k == CascadeBatchKernel::Avx2 ? "AVX2" : "AVX-512VL";
}

// Reference: simulate_axes' rows from each axis' own CascadeAxis::step (with the full-rate trace), as its header
// documents them: row 0 at rest at the first setpoint, row k+1 after one Te on setpoint k, the feedforward the
// backward differences of the setpoints, the last setpoint (and gains) held over the settling rows, jerk the backward
// difference of the accelerations.
inline AxisResponse cascade_reference(const core::Setpoints& sp, const core::Machine& m, const GainSchedule* gains,
                                      double settle_s) {
  const double te = sp.period_s;
  const Eigen::Index n_set = sp.samples(), n_axes = sp.position.cols();
  const Eigen::Index rows = n_set + static_cast<Eigen::Index>(std::llround(settle_s / te));
  AxisResponse out;
  out.period_s = te;
  for (Eigen::MatrixXd* c : {&out.position, &out.velocity, &out.acceleration, &out.jerk, &out.current_A,
                             &out.current_setpoint_A, &out.current_mean_A, &out.current_peak_A})
    c->setZero(rows, n_axes);
  out.trace.resize(static_cast<std::size_t>(n_axes));
  for (Eigen::Index a = 0; a < n_axes; ++a) {
    const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(a)];
    CascadeAxis model(*ax.drive, te, ax.kind);
    model.reset(sp.position(0, a));
    const Eigen::Index nin = model.inner_steps();
    FullRateTrace& t = out.trace[static_cast<std::size_t>(a)];
    t.period_s = ax.drive->current_period_s;
    for (Eigen::ArrayXd* v : {&t.position, &t.velocity, &t.current_A, &t.current_setpoint_A, &t.voltage_V})
      v->setZero((rows - 1) * nin + 1);
    std::vector<InnerSample> inner(static_cast<std::size_t>(nin));
    AxisSample s = model.sample();
    double prev_x = sp.position(0, a), prev_v = 0.0, prev_acc = 0.0;
    for (Eigen::Index k = 0; k < rows; ++k) {
      out.position(k, a) = s.position;
      out.velocity(k, a) = s.velocity;
      out.acceleration(k, a) = s.acceleration;
      out.jerk(k, a) = (s.acceleration - prev_acc) / te;
      prev_acc = s.acceleration;
      out.current_A(k, a) = s.current_A;
      out.current_mean_A(k, a) = s.current_mean_A;
      out.current_peak_A(k, a) = s.current_peak_A;
      out.current_setpoint_A(k, a) = s.current_setpoint_A;
      if (k + 1 == rows) break;
      const Eigen::Index ks = std::min(k, n_set - 1);
      AxisCommand c;
      c.position = sp.position(ks, a);
      c.velocity = (c.position - prev_x) / te;
      c.acceleration = (c.velocity - prev_v) / te;
      prev_x = c.position;
      prev_v = c.velocity;
      if (gains && gains->kv_per_s.size()) c.kv_per_s = gains->kv_per_s(ks, a);
      if (gains && gains->kf.size()) c.kf = gains->kf(ks, a);
      s = model.step(c, inner.data());
      for (Eigen::Index n = 0; n < nin; ++n) {
        const InnerSample& q = inner[static_cast<std::size_t>(n)];
        t.position[k * nin + n] = q.position;
        t.velocity[k * nin + n] = q.velocity;
        t.current_A[k * nin + n] = q.current_A;
        t.current_setpoint_A[k * nin + n] = q.current_setpoint_A;
        t.voltage_V[k * nin + n] = q.voltage_V;
      }
    }
    const InnerSample q = model.inner_sample();
    const Eigen::Index last = (rows - 1) * nin;
    t.position[last] = q.position, t.velocity[last] = q.velocity, t.current_A[last] = q.current_A;
    t.current_setpoint_A[last] = q.current_setpoint_A, t.voltage_V[last] = q.voltage_V;
  }
  return out;
}

}  // namespace vmsim::drives::test
