#include "drives/discrete_tf_axis.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace vmsim::drives {

DiscreteTfAxis::DiscreteTfAxis(DiscreteTf tf) : tf_(std::move(tf)) {
  if (tf_.nk < 1) throw core::Error(fmt::format("the input delay nk must be >= 1 sample, found {}", tf_.nk));
  if (tf_.nb() < 1) throw core::Error("the numerator B has no coefficient");
  if (!tf_.a.allFinite() || !tf_.b.allFinite()) throw core::Error("a coefficient is not finite");
  if (!(tf_.period_s > 0.0 && std::isfinite(tf_.period_s)))
    throw core::Error(fmt::format("the period must be positive, found {} s", tf_.period_s));
  const double r = spectral_radius(tf_.a);
  if (!(r < 1.0)) throw core::Error(fmt::format("the model is unstable: a pole of A lies at |z| = {:.6g} (>= 1)", r));
  u_.assign(static_cast<std::size_t>(tf_.nk + tf_.nb() - 1), 0.0);
  y_.assign(static_cast<std::size_t>(std::max(tf_.na(), 1)), 0.0);
}

void DiscreteTfAxis::reset(double position) {
  origin_ = position;
  std::fill(u_.begin(), u_.end(), 0.0);
  std::fill(y_.begin(), y_.end(), 0.0);
  velocity_ = 0.0;
}

AxisSample DiscreteTfAxis::step(const AxisCommand& command) {
  // Shift the input history: u_[0] becomes u(k).
  for (std::size_t i = u_.size() - 1; i > 0; --i) u_[i] = u_[i - 1];
  u_[0] = command.position - origin_;
  double y = 0.0;
  for (int i = 1; i <= tf_.na(); ++i) y -= tf_.a[i - 1] * y_[static_cast<std::size_t>(i - 1)];
  for (int j = 1; j <= tf_.nb(); ++j) y += tf_.b[j - 1] * u_[static_cast<std::size_t>(tf_.nk + j - 2)];
  const double prev = y_[0];
  for (std::size_t i = y_.size() - 1; i > 0; --i) y_[i] = y_[i - 1];
  y_[0] = y;
  AxisSample s;
  s.position = origin_ + y;
  s.velocity = (y - prev) / tf_.period_s;
  s.acceleration = (s.velocity - velocity_) / tf_.period_s;
  velocity_ = s.velocity;
  return s;
}

std::unique_ptr<AxisModel> DiscreteTfAxis::clone() const { return std::make_unique<DiscreteTfAxis>(*this); }

}  // namespace vmsim::drives
