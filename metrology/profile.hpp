#pragma once
// Profiles (1-D): a stylus trace (a Dektak export, an X3P PRF, a .sur profile) or a line across a surface; their
// form removal, the Gaussian profile filter, the profile parameters of ISO 21920-2, and a measured profile held
// against a line across a predicted surface.
#include "core/height_grid.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <vector>

namespace vmsim::metrology {

// Heights at x = x0 + i dx (uniform sampling, as the parameters and the filter need). NaN = invalid.
struct LineScan {
  double x0_mm = 0.0, dx_mm = 1.0;
  Eigen::ArrayXd z_mm;
  Eigen::Index size() const { return z_mm.size(); }
  double x(Eigen::Index i) const { return x0_mm + static_cast<double>(i) * dx_mm; }
  double length_mm() const { return static_cast<double>(z_mm.size()) * dx_mm; }
};

// A one-row grid as a line scan (X3P PRF, .sur profiles keep their heights in one row), and back.
LineScan line_scan_of_row(const core::HeightGrid& grid, Eigen::Index row = 0);
core::HeightGrid grid_of_line_scan(const LineScan& p);

// The nodes with x in [x_from, x_to] (mm). Throws core::Error when fewer than 2 remain.
LineScan crop(const LineScan& p, double x_from_mm, double x_to_mm);

// Least-squares polynomial in x of degree `degree` (0: the mean line; 1: the least-squares line) through the valid
// points, subtracted. Throws core::Error when there are fewer valid points than terms.
LineScan remove_profile_form(const LineScan& p, int degree);

// The mean line of the Gaussian profile filter of ISO 16610-21 with cut-off `cutoff_mm`: weighting function
// s(x) = 1/(alpha lc) exp(-pi (x / (alpha lc))^2), alpha = sqrt(ln 2 / pi), which transmits 50 % of a sinusoid of
// wavelength lc. The kernel is truncated at |x| <= lc (where it has fallen to 6.5e-7 of its peak). At the ends and
// next to invalid points the weights are renormalised over the valid points inside the window (the zero-order
// end-effect correction of ISO 16610-28); invalid points stay invalid.
LineScan gaussian_profile_mean_line(const LineScan& p, double cutoff_mm);
// S-filter: keeps the mean line (removes wavelengths shorter than lambda_s). L-filter: the profile minus its mean
// line with cut-off lambda_c (the roughness profile).
inline LineScan profile_lowpass(const LineScan& p, double cutoff_mm) {
  return gaussian_profile_mean_line(p, cutoff_mm);
}
LineScan profile_highpass(const LineScan& p, double cutoff_mm);

struct ProfileParameters {
  std::size_t points = 0;           // valid points in the evaluation length
  double evaluation_length_mm = 0;  // points x spacing
  int sections = 0;                 // sections used for Rp, Rv, Rz, Rzx
  double section_length_mm = 0;
  double mean_mm = 0;  // the reference line's height (heights are measured from it)
  double Ra_mm = 0, Rq_mm = 0, Rsk = 0, Rku = 0;
  double Rp_mm = 0, Rv_mm = 0, Rz_mm = 0;  // means over the sections
  double Rt_mm = 0, Rzx_mm = 0;            // over the whole evaluation length; the largest section height
};

// The height parameters of ISO 21920-2 over the whole profile as given (the evaluation length), the heights taken
// from their mean (remove the form and filter first: then the mean is the least-squares or filter mean line):
//   Ra = mean |z|, Rq = sqrt(mean z^2), Rsk = mean z^3 / Rq^3, Rku = mean z^4 / Rq^4 (over the evaluation length);
//   Rp, Rv, Rz = the means over the sections of the largest peak height, the largest pit depth, and their sum
//   (ISO 21920-2's section parameters; Rz is the "Rz" of ISO 4287 / DIN as Dektak's RzDin);
//   Rt = max z - min z over the evaluation length; Rzx = the largest section height.
// The sections are `sections` consecutive pieces of equal point count (ISO 21920-3's default is 5 of the cut-off
// length each), or consecutive pieces of `section_length_mm` (as many whole ones as fit, at least one) when it is
// positive. Throws core::Error when the profile has no valid point.
ProfileParameters profile_parameters(const LineScan& p, int sections = 5, double section_length_mm = 0.0);

// The procedure a profile's parameters come from, in order: the form removed (`level`: 0 the mean line, 1 the
// least-squares line, N a polynomial), the Gaussian filters (S: keep the mean line with cut-off lambda_s; L: remove
// the mean line with cut-off lambda_c), then, after an L-filter, lambda_c / 2 dropped at each end (the run-in and
// run-out that ISO 21920-3 adds to the evaluation length, where the filter's mean line leans on one side only).
// The sections for Rp, Rv, Rz are then lambda_c long (ISO 21920-3: the section length is the cut-off), or, with no
// L-filter, `sections` equal pieces of the evaluation length.
struct ProfileFilter {
  char kind = 'L';  // 'S' or 'L'
  double cutoff_mm = 0.8;
};
struct ProfileEvaluation {
  int level = 1;
  std::vector<ProfileFilter> filters;
  int sections = 5;
};
struct EvaluatedProfile {
  LineScan profile;  // the profile the parameters are computed on (form removed, filtered, ends dropped)
  ProfileParameters parameters;
};
EvaluatedProfile evaluate_profile(const LineScan& p, const ProfileEvaluation& how);

// The heights along the straight line from (x0, y0) to (x1, y1) across a grid, every `step_mm` from s = 0 at the
// start (bilinear; NaN off the grid and in cells with an invalid corner). x of the result is the distance along
// the line.
LineScan line_across(const core::HeightGrid& grid, double x0_mm, double y0_mm, double x1_mm, double y1_mm,
                     double step_mm);

// A measured profile held against a line across a predicted surface. The measured profile's x runs along the line
// from its start: s = x - x_first + shift. With `align`, the shift along the line is searched (every predicted
// sample over the range where at least half of the measured profile lies on the line, then refined to a
// hundredth of the spacing) and, for each shift, the measured heights' offset and tilt relative to the prediction
// are fitted by least squares: a stylus trace's datum and levelling are its own, so only its shape is compared.
// Without `align` the profile lies as measured (shift 0, no offset or tilt).
struct ProfileAlignmentOptions {
  bool align = true;
  double shift_mm = 0.0;  // the shift when not aligning (or the centre of the search)
};
struct ProfileComparison {
  double line_length_mm = 0;
  double shift_mm = 0;             // measured x_first sits at s = shift along the line
  double offset_mm = 0, tilt = 0;  // fitted: measured ~ predicted + offset + tilt * (s - s_centre)
  double s_centre_mm = 0;
  LineScan measured, predicted;  // on the measured samples, x = s along the line; predicted NaN off the line
  LineScan deviation;            // measured (aligned) - predicted, where both are valid
  std::size_t points = 0;        // samples where both are valid
  double rms_mm = 0, mean_mm = 0, min_mm = 0, max_mm = 0;
};
ProfileComparison compare_profile(const LineScan& measured, const core::HeightGrid& predicted, double x0_mm,
                                  double y0_mm, double x1_mm, double y1_mm,
                                  const ProfileAlignmentOptions& options = {});

}  // namespace vmsim::metrology
