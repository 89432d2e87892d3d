#pragma once
// A confocal point sensor (STIL-style chromatic confocal probe) scanning a predicted surface, to plan a scan: what
// grid step, spot and noise resolve, and where steep flanks lose the signal.
#include "core/height_grid.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>

namespace vmsim::metrology {

struct SensorOptions {
  double step_mm = 0.005;          // scan grid step, x and y
  double spot_mm = 0.004;          // spot diameter, taken as the full width at half maximum of a Gaussian spot
  double noise_mm = 0.0001;        // height noise, standard deviation
  double max_slope_deg = 30.0;     // flanks steeper than this return no signal (the objective's aperture angle)
  double dropout_probability = 0;  // further random dropouts, per point
  std::uint64_t seed = 1;          // noise and dropouts are a function of (seed, node): repeatable, thread-independent
  // Scanned area (mm); the whole predicted surface when empty.
  std::optional<double> x_min_mm, x_max_mm, y_min_mm, y_max_mm;
};

struct SensorReport {
  std::size_t points = 0;          // scan nodes
  std::size_t slope_dropouts = 0;  // flank steeper than max_slope_deg
  std::size_t random_dropouts = 0;
  std::size_t outside = 0;   // not over valid predicted surface
  double spot_sigma_mm = 0;  // the Gaussian spot's standard deviation
  // Wavelength whose amplitude the spot halves: exp(-2 pi^2 sigma^2 / L^2) = 1/2.
  double half_amplitude_wavelength_mm = 0;
};

// The measured heights: the predicted surface averaged over the spot (a Gaussian low-pass of the heights, edges
// renormalised as gaussian_mean_surface), sampled bilinearly at the scan's nodes, with Gaussian noise; points whose
// smoothed surface is steeper than max_slope_deg, or that draw a random dropout, are invalid (NaN).
core::HeightGrid simulate_scan(const core::HeightGrid& predicted, const SensorOptions& options,
                               SensorReport* report = nullptr);

}  // namespace vmsim::metrology
