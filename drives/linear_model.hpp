#pragma once
// The linearised closed-loop frequency response of one axis's cascade, G = X / X_d (drives/cascade_axis without
// friction, saturation or position-dependent gravity), built from the loop elements in the frequency domain. Chen et
// al. 2016 plans feeds from |G(jw)| (its circular contour-error model R (1 - |G(j v/R)|)); OGA and the tests use it
// too.
//
// Two evaluations of the same loop structure, both following drives/cascade_axis.hpp's timing rules:
// - closed_loop_elements(): every loop element on its own at s = jw — the discrete PIs as D(e^{jwT}), the winding
//   with back-EMF and the shaft continuous, the voltage held over Tc as the ZOH (1 - e^{-jwT})/(jwT), the delays
//   z^-d, the feedforward set points' backward differences (1 - z^-1)/Te — and each change of rate between loops as
//   the hold upsampler it is: a sequence held over T and read at T' (T' divides T) is, at baseband,
//   zoh(T)/zoh(T'), a delay (T - T')/2 rather than T/2, because the faster loop reads each new value at the
//   instant it appears. Only the aliasing of the inner loops' images back to baseband is neglected: at the
//   frequencies of contouring (|G| near 1) this model and the simulation agree to about 1e-6 (tests/drives);
//   near the loops' bandwidths (100 Hz and up) they part by a few %.
// - closed_loop(): the same cascade's exact sampled-data response. The inner cascade (current PI at Tc on the
//   ZOH-discretised winding and shaft, velocity PI at Tv) is lifted to one linear map per Te,
//   s[k+1] = Phi s[k] + Gamma [w_cmd, i_ff][k], by composing the Tv and Tc updates as matrices; its response
//   P(e^{jwTe}) = C (e^{jwTe} I - Phi)^-1 Gamma is closed by the position loop's elements:
//     G = [(Kv z^-dp + KF z^-df (1 - z^-1)/Te) P_v + KA J/(Kt r) z^-df (1 - z^-1)^2/Te^2 P_i] / (1 + Kv P_v),
//   z = e^{jwTe}. It is what the simulation's rows (t_k = k Te) give in steady state for a sinusoid sampled at Te,
//   aliasing included, up to the Nyquist frequency pi/Te.
#include "core/machine.hpp"

#include <Eigen/Core>

#include <complex>

namespace vmsim::drives {

class LinearAxisModel {
 public:
  // te_s: the position-loop period. Throws core::Error when the loop periods do not nest (as CascadeAxis does).
  LinearAxisModel(const core::DriveParams& params, double te_s);

  // G(e^{jwTe}) at angular frequency omega (rad/s, below pi/Te), with the drive's own Kv and KF or given ones.
  std::complex<double> closed_loop(double omega_rad_s) const;
  std::complex<double> closed_loop(double omega_rad_s, double kv_per_s, double kf) const;
  // G(jw) from the loop elements, the inner loops' aliasing neglected.
  std::complex<double> closed_loop_elements(double omega_rad_s) const;
  std::complex<double> closed_loop_elements(double omega_rad_s, double kv_per_s, double kf) const;

  // The inner cascade sampled at Te: from the velocity command held over Te (axis units/s) to the position at the
  // next samples, and from the current feedforward held over Te (A) to the position.
  std::complex<double> velocity_to_position(double omega_rad_s) const;
  std::complex<double> current_to_position(double omega_rad_s) const;

  // Chen et al.'s circular contour-error model: steady radial error R (1 - |G(j v/R)|) (positive: inside the circle)
  // of a circle of radius R (axis units) at path speed v (axis units/s), both axes having these parameters.
  double circle_radial_error(double radius, double speed) const;

  // The cascade's poles in the z-plane, one step per Te (the lifted inner cascade of closed_loop()): with the position
  // loop closed at gain kv_per_s (6), or of the velocity and current loops alone, the position loop open (5: the
  // position's own integrator, z = 1, left out). |z| < 1 for every pole: the loop is stable.
  Eigen::VectorXcd closed_loop_poles(double kv_per_s) const;
  Eigen::VectorXcd closed_loop_poles() const { return closed_loop_poles(params_.kv_per_s); }
  Eigen::VectorXcd inner_poles() const;

  double period_s() const { return te_; }
  const core::DriveParams& params() const { return params_; }

 private:
  std::complex<double> lifted(double omega_rad_s, int input) const;
  std::complex<double> close(std::complex<double> z, std::complex<double> pv, std::complex<double> pi, double kv,
                             double kf) const;

  core::DriveParams params_;
  double te_;
  // Lifted inner cascade over one Te: state (i, w, x, current integrator, velocity integrator, current setpoint).
  Eigen::Matrix<double, 6, 6> phi_;
  Eigen::Matrix<double, 6, 2> gamma_;
};

}  // namespace vmsim::drives
