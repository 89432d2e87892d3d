#pragma once
// The cascaded feed drive of the feed-drive simulation paper (section 2, Fig. 2) and Duong et al. (section III.C, Fig.
// 6) as an AxisModel: position loop P + velocity and torque feedforward at Te, velocity PI, current PI on the motor's
// R-L winding with back-EMF, and the mechanics at the motor shaft with viscous, Coulomb (optionally Stribeck) friction
// and gravity.
//
// Timing, which drives/linear_model reproduces in the frequency domain (both follow these rules):
// - Step k covers [t_k, t_k + Te). At t_k the position loop reads the actual position x(t_k) and the command
//   received at step k - position_delay_samples (x_d) and k - feedforward_delay_samples (v_d, a_d); its outputs
//   (velocity command, current feedforward) are held over the whole period (zero-order hold).
// - The velocity loop runs at t_k + m*Tv, reading the motor speed at that instant; its current setpoint is held for
//   Tv. The current loop runs at t_k + n*Tc, reading the current; its voltage is held for Tc. No computation delay
//   inside a loop: a delay is modelled only where the seed puts one (the position and feedforward paths).
// - Te must be a whole number of velocity periods and Tv a whole number of current periods (checked).
//
// Integration: the electrical and mechanical states (i, w, x) form a linear system driven by the held voltage and
// the load torque. Each current period is integrated exactly (zero-order-hold discretisation by the matrix
// exponential); the only approximation is that the non-linear load torques (Coulomb/Stribeck friction, tilting
// gravity) are evaluated at the start of each Tc and held over it (error O(Tc) in those torques only; they vanish
// without friction and with constant or no gravity, where the integration is exact to rounding).
#include "core/machine.hpp"
#include "drives/axis_model.hpp"

#include <memory>
#include <vector>

namespace vmsim::drives {

// longer / shorter as a whole number, or core::Error naming `what`: the loops are scheduled by counting inner
// periods, so a period that does not nest would drift against its outer loop (the linear model counts the same way).
int whole_ratio(double longer, double shorter, const char* what);

// One current-loop sample (load side, axis units): the state at the start of a current period and the current
// setpoint and voltage held over it.
struct InnerSample {
  double position = 0.0, velocity = 0.0, current_A = 0.0, current_setpoint_A = 0.0, voltage_V = 0.0;
};

class CascadeAxis final : public AxisModel {
 public:
  // te_s: the position-loop period (the job's Te). Throws core::Error on parameters the model cannot run
  // (periods that do not nest, non-positive values); the message names the parameter but no file.
  CascadeAxis(const core::DriveParams& params, double te_s, core::AxisKind kind);

  // At rest at `position` holding its load: speed 0, the current that balances gravity (0 without gravity), both
  // PI integrators preset to that steady state, the delay lines filled with `position`. Throws core::Error when the
  // gravity torque at `position` needs more than the current limit (the axis could not hold its load).
  void reset(double position) override;
  AxisSample step(const AxisCommand& command) override;
  std::unique_ptr<AxisModel> clone() const override;

  // As step(), also writing the inner_steps() current-loop samples of the period to trace[0 .. inner_steps()-1].
  AxisSample step(const AxisCommand& command, InnerSample* trace);
  // The state now (what step() returns at the end of a period; after reset(): the resting state).
  AxisSample sample() const;
  InnerSample inner_sample() const;
  int inner_steps() const { return current_per_te_; }  // current-loop periods per Te
  double current_period_s() const { return params_.current_period_s; }
  const core::DriveParams& params() const { return params_; }

 private:
  friend class CascadeBatch;  // steps several axes together on this state (drives/cascade_batch)

  template <bool kTrace>
  AxisSample advance(const AxisCommand& command, InnerSample* trace);
  void rest_at(double position);
  void velocity_loop(double w_cmd, double i_ff);
  void current_loop();
  void plant(double voltage);
  double gravity_torque() const;
  double friction_level(double abs_w) const;

  core::DriveParams params_;
  core::AxisKind kind_;
  double te_;
  int current_per_te_ = 1, current_per_velocity_ = 1;
  // Constants derived once from the parameters.
  double r_ = 1.0, inv_r_ = 1.0;       // axis units per motor rad, and its inverse
  double kpv_ = 0.0, kiv_ = 0.0;       // velocity PI: proportional gain, integral gain x Tv
  double kpc_ = 0.0, kic_ = 0.0;       // current PI: proportional gain, integral gain x Tc
  double ff_current_per_accel_ = 0.0;  // ka * J / (Kt * r): current feedforward per axis acceleration
  double phi_[3][3] = {}, gam_u_[3] = {}, gam_t_[3] = {};  // exact ZOH step of (i, w, x) over Tc
  double stuck_a_ = 0.0, stuck_b_ = 0.0;                   // the winding alone (w = 0): i <- a i + b u
  bool friction_ = false;
  double breakaway_Nm_ = 0.0;
  double stick_window_ = 0.0;  // |w| below which a shaft that cannot break loose sticks (rad/s)
  // State.
  double i_ = 0.0, w_ = 0.0, x_ = 0.0;  // current (A), motor speed (rad/s), load position (axis units)
  double ic_ = 0.0, iv_ = 0.0;          // current-PI integrator (V), velocity-PI integrator (A)
  double iset_ = 0.0, u_ = 0.0;         // held current setpoint (A) and voltage (V)
  // Delay lines (the feed-drive simulation paper section 2.2): ring buffers of length delay + 1; the oldest entry is
  // the delayed command.
  std::vector<double> pos_line_, vel_line_, acc_line_;
  int pos_head_ = 0, ff_head_ = 0;
};

std::unique_ptr<AxisModel> make_cascade_axis(const core::DriveParams& params, double te_s, core::AxisKind kind);

}  // namespace vmsim::drives
