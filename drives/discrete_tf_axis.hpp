#pragma once
// The identified discrete transfer function of the predictive-compensation paper (drives/sysid) as an AxisModel, the
// second implementation beside the physical cascade: the command position in, the encoder position out, nothing else
// (no current).
#include "drives/axis_model.hpp"
#include "drives/discrete_tf.hpp"

#include <memory>
#include <vector>

namespace vmsim::drives {

class DiscreteTfAxis final : public AxisModel {
 public:
  // Throws core::Error for a model that cannot run: nk < 1, nb < 1, an unstable A (pole on or outside the unit
  // circle), non-finite coefficients or period.
  explicit DiscreteTfAxis(DiscreteTf tf);

  // At rest at `position`: the model's state is its deviation from this point (drives/sysid.hpp), all zero.
  void reset(double position) override;
  // Row k+1 of a simulation from setpoint k: y(k+1) = -sum a_i y(k+1-i) + sum b_j u(k+2-nk-j). Velocity and
  // acceleration are backward differences over Te; the current fields are 0 (the model has none).
  AxisSample step(const AxisCommand& command) override;
  std::unique_ptr<AxisModel> clone() const override;

  const DiscreteTf& tf() const { return tf_; }

 private:
  DiscreteTf tf_;
  double origin_ = 0.0;
  std::vector<double> u_;  // u_[i] = u(k - i), deviations
  std::vector<double> y_;  // y_[i] = y(k - i)
  double velocity_ = 0.0;
};

}  // namespace vmsim::drives
