#include "metrology/compare.hpp"
#include "core/units.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"
#include "metrology/mesh_distance.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::metrology {

namespace {

using core::units::kPi;

RigidTransform registered(const core::HeightGrid& scan, const core::HeightGrid& pred,
                          const SurfaceCompareOptions& options, std::optional<RegistrationResult>& result) {
  const RigidTransform given = options.initial.value_or(RigidTransform{});
  if (!options.align) return given;
  RegistrationOptions ro;
  ro.loss = options.loss == RobustLoss::Huber ? RobustLoss::Huber : RobustLoss::Tukey;
  ro.tuning = options.loss == RobustLoss::Huber ? 1.345 : 4.685;
  ro.regions = options.regions;
  ro.initial = options.initial;
  result = register_scan(scan, pred, ro);
  return result->transform;
}

void find_path_direction(const core::HeightGrid& pred, const SurfaceCompareOptions& options, SurfaceComparison& c) {
  if (options.path_direction_rad) {
    c.path_direction_rad = *options.path_direction_rad;
    c.path_direction_from = PathDirectionFrom::Given;
    return;
  }
  const Lay lay = lay_of(pred);
  c.path_direction_rad = lay.direction_rad;
  c.path_direction_from = PathDirectionFrom::Lay;
  c.lay_anisotropy = lay.anisotropy;
  if (lay.anisotropy < 0.2) c.path_direction_rad = 0, c.path_direction_from = PathDirectionFrom::NoLay;
}

void find_marks_and_profiles(const Prediction& prediction, const SurfaceCompareOptions& options, SurfaceComparison& c) {
  const core::HeightGrid& pred = prediction.grid;
  const bool mesh = prediction.mesh.has_value();
  find_path_direction(pred, options, c);
  // Regions of fewer than 9 nodes (3 x 3) are the scan's noise crossing the threshold, not marks.
  c.marks = find_marks(c.deviation, options.mark_threshold_mm, 10, c.path_direction_rad, 9);
  if (mesh)
    for (const Mark& m : c.marks) {  // scan-frame position carried into the part frame
      double z = 0;
      sample_bilinear(c.scan, m.x_mm, m.y_mm, z);
      c.marks_in_part_mm.push_back(c.transform.apply({m.x_mm, m.y_mm, z}).head<2>());
    }
  const core::HeightGrid& dev = c.deviation;
  const double across = c.path_direction_rad + kPi / 2;
  for (std::size_t k = 0; k < c.marks.size() && k < 3; ++k) {
    const Mark& m = c.marks[k];
    const double half = std::max({3 * m.width_mm, 30 * dev.dx_mm, 0.2}), step = std::min(dev.dx_mm, dev.dy_mm) / 2;
    MarkProfile p;
    p.deviation = profile(dev, m.x_mm, m.y_mm, across, half, step);
    p.measured = profile(mesh ? c.scan : c.measured_on, m.x_mm, m.y_mm, across, half, step);
    if (!mesh) p.predicted = profile(pred, m.x_mm, m.y_mm, across, half, step);
    c.mark_profiles.push_back(std::move(p));
  }
}

void common_area_parameters(const core::HeightGrid& pred, const SurfaceProcessing& how, SurfaceComparison& c) {
  core::HeightGrid mc = c.measured_on, pc = pred;
  for (Eigen::Index k = 0; k < mc.z_mm.size(); ++k)
    if (!std::isfinite(mc.z_mm.data()[k]) || !std::isfinite(pc.z_mm.data()[k]))
      mc.z_mm.data()[k] = pc.z_mm.data()[k] = NAN;
  FormFit fit;
  c.measured_areal = areal_parameters(process_surface(mc, how, &fit));
  if (how.level > 0) c.measured_form = fit;
  c.predicted_areal = areal_parameters(process_surface(pc, how));
}

}  // namespace

Prediction prediction_of_mesh(core::TriangleMesh mesh, double spacing_mm) {
  Prediction p;
  p.grid = rasterize_top(mesh, spacing_mm);
  p.mesh = std::move(mesh);
  return p;
}

DeviationStats deviation_stats(const core::HeightGrid& d) {
  DeviationStats s;
  double sum = 0, s2 = 0, sa = 0, lo = HUGE_VAL, hi = -HUGE_VAL;
  for (Eigen::Index k = 0; k < d.z_mm.size(); ++k) {
    const double v = d.z_mm.data()[k];
    if (!std::isfinite(v)) continue;
    ++s.points, sum += v, s2 += v * v, sa += std::abs(v), lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (s.points) {
    const double n = static_cast<double>(s.points);
    s.min = lo, s.max = hi, s.mean = sum / n, s.rms = std::sqrt(s2 / n), s.mean_abs = sa / n;
  }
  return s;
}

SurfaceComparison compare_surfaces(core::HeightGrid scan, const Prediction& prediction,
                                   const SurfaceCompareOptions& options) {
  const core::HeightGrid& pred = prediction.grid;
  SurfaceComparison c;
  auto t0 = core::Clock::now();
  if (options.outlier_sigma > 0) {  // spikes: masked, counted, never zeroed
    OutlierOptions oo;
    oo.k_sigma = options.outlier_sigma;
    c.outliers = mask_outliers(scan, oo);
  }
  c.scan = std::move(scan);
  c.seconds.outliers = core::seconds_since(t0);

  t0 = core::Clock::now();
  c.transform = registered(c.scan, pred, options, c.registration);
  c.seconds.registration = core::seconds_since(t0);

  t0 = core::Clock::now();
  c.measured_on = resample_scan(c.scan, c.transform, pred);
  c.deviation =
      prediction.mesh ? mesh_deviation(c.scan, c.transform, *prediction.mesh) : deviation(c.measured_on, pred);
  c.stats = deviation_stats(c.deviation);
  if (c.stats.points == 0) throw core::Error("compare: the aligned scan and the prediction do not overlap anywhere");
  c.seconds.deviation = core::seconds_since(t0);

  t0 = core::Clock::now();
  find_marks_and_profiles(prediction, options, c);
  c.seconds.marks = core::seconds_since(t0);

  t0 = core::Clock::now();
  common_area_parameters(pred, options.processing, c);
  c.seconds.areal = core::seconds_since(t0);
  return c;
}

ProfileSurfaceComparison compare_profile_to_surface(const LineScan& measured, const core::HeightGrid& predicted,
                                                    double x0_mm, double y0_mm, double x1_mm, double y1_mm,
                                                    const ProfileAlignmentOptions& alignment,
                                                    const ProfileEvaluation& how) {
  ProfileSurfaceComparison r;
  r.along = compare_profile(measured, predicted, x0_mm, y0_mm, x1_mm, y1_mm, alignment);
  // The parameters of both on the samples where both are valid, after the same form removal and filters.
  LineScan pm = r.along.measured, pp = r.along.predicted;
  for (Eigen::Index i = 0; i < pm.size(); ++i)
    if (!std::isfinite(pm.z_mm[i]) || !std::isfinite(pp.z_mm[i])) pm.z_mm[i] = pp.z_mm[i] = NAN;
  Eigen::Index first = 0, last = pm.size() - 1;
  while (first < last && !std::isfinite(pm.z_mm[first])) ++first;
  while (last > first && !std::isfinite(pm.z_mm[last])) --last;
  pm = crop(pm, pm.x(first), pm.x(last)), pp = crop(pp, pp.x(first), pp.x(last));
  r.measured = evaluate_profile(pm, how);
  r.predicted = evaluate_profile(pp, how);
  return r;
}

}  // namespace vmsim::metrology
