#pragma once
// Areal filters and outlier masking. Invalid points (NaN) are never filled in and never counted as zero heights.
#include "core/height_grid.hpp"

#include <cstddef>

namespace vmsim::metrology {

// The mean surface of the Gaussian areal filter of ISO 16610-61 with nesting index (cut-off) `cutoff_mm`:
// weighting function s(x, y) = 1/(alpha^2 lc^2) exp(-pi (x^2 + y^2) / (alpha^2 lc^2)), alpha = sqrt(ln 2 / pi),
// which transmits 50 % of a sinusoid of wavelength lc. The kernel is truncated at |x|, |y| <= lc (where it has
// fallen to 6.5e-7 of its peak) and applied separably.
// Edges and invalid points: at each node the weights are renormalised over the valid points inside the window
// (the zero-order end-effect correction of ISO 16610-28, i.e. a normalised convolution), so the mean surface is
// defined up to the edge without padding or mirroring; near edges it is a one-sided weighted mean, which is
// biased on sloping surfaces (remove the form first). Invalid nodes stay invalid.
core::HeightGrid gaussian_mean_surface(const core::HeightGrid& grid, double cutoff_mm);

// S-filter (ISO 25178-3): removes the short wavelengths, keeps the mean surface (the same as gaussian_mean_surface).
inline core::HeightGrid gaussian_lowpass(const core::HeightGrid& g, double cutoff_mm) {
  return gaussian_mean_surface(g, cutoff_mm);
}
// L-filter (ISO 25178-3): removes the long wavelengths (form and waviness): the grid minus its mean surface.
core::HeightGrid gaussian_highpass(const core::HeightGrid& grid, double cutoff_mm);

struct OutlierOptions {
  int window = 5;        // odd window side, nodes: the farthest ring of neighbours used at edges and holes
  double k_sigma = 6.0;  // threshold in robust standard deviations
};
struct OutlierReport {
  std::size_t masked = 0;   // points made invalid
  double sigma_mm = 0;      // robust standard deviation of the departures (1.4826 MAD)
  double threshold_mm = 0;  // k_sigma * sigma_mm
};
// Spikes (a confocal sensor's false returns): each valid point is compared with predictions of its height, the
// means of pairs of valid neighbours symmetric about it (exact on any plane, so steep flanks are not spikes), from
// the nearest ring of 8 neighbours, and from the next rings of the window only where the nearest gives fewer than
// two pairs (edges, holes). A point is a spike when it departs from the median of its predictions by more than k
// robust standard deviations of all such departures (1.4826 MAD), and from every single prediction by as much: a
// point on a crease (a track's edge, a sharp corner) departs from the median but agrees with the pair along the
// crease. Spikes are made invalid (NaN); points without two pairs (corners, isolated points) are not judged. The
// report says how many were masked: nothing goes silently.
OutlierReport mask_outliers(core::HeightGrid& grid, const OutlierOptions& options = {});

}  // namespace vmsim::metrology
