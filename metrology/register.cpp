#include "metrology/register.hpp"
#include "core/units.hpp"

#include "core/error.hpp"
#include "metrology/filter.hpp"
#include "metrology/form.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace vmsim::metrology {

Eigen::Vector3d RigidTransform::rotation_vector() const {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

RigidTransform RigidTransform::from_xyz_rxyz(double x, double y, double z, double rx, double ry, double rz) {
  RigidTransform T;
  T.R = (Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
  T.t = Eigen::Vector3d(x, y, z);
  return T;
}

bool sample_bilinear(const core::HeightGrid& g, double x, double y, double& z, double* gx, double* gy) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  if (nx < 2 || ny < 2) return false;
  const double fx = (x - g.x0_mm) / g.dx_mm, fy = (y - g.y0_mm) / g.dy_mm;
  if (!(fx >= 0) || !(fy >= 0) || fx > static_cast<double>(nx - 1) || fy > static_cast<double>(ny - 1)) return false;
  const Eigen::Index i = std::min<Eigen::Index>(static_cast<Eigen::Index>(fx), nx - 2);
  const Eigen::Index j = std::min<Eigen::Index>(static_cast<Eigen::Index>(fy), ny - 2);
  const double u = fx - static_cast<double>(i), v = fy - static_cast<double>(j);
  const double z00 = g.z_mm(j, i), z10 = g.z_mm(j, i + 1), z01 = g.z_mm(j + 1, i), z11 = g.z_mm(j + 1, i + 1);
  if (!std::isfinite(z00) || !std::isfinite(z10) || !std::isfinite(z01) || !std::isfinite(z11)) return false;
  z = (1 - u) * (1 - v) * z00 + u * (1 - v) * z10 + (1 - u) * v * z01 + u * v * z11;
  if (gx) *gx = ((1 - v) * (z10 - z00) + v * (z11 - z01)) / g.dx_mm;
  if (gy) *gy = ((1 - u) * (z01 - z00) + u * (z11 - z10)) / g.dy_mm;
  return true;
}

namespace {

using core::units::kNaN;
const char* const kDirection[6] = {"rotation x",    "rotation y",    "rotation z",
                                   "translation x", "translation y", "translation z"};

// The predicted surface with its central-difference gradients (for smooth normals between nodes).
struct Target {
  core::HeightGrid z, gx, gy;
  explicit Target(core::HeightGrid g) : z(std::move(g)) {
    gx = z, gy = z;
    const Eigen::Index nx = z.nx(), ny = z.ny();
#pragma omp parallel for schedule(static)
    for (Eigen::Index j = 0; j < ny; ++j)
      for (Eigen::Index i = 0; i < nx; ++i) {
        const auto d = [&](bool m, bool p, double zm, double z0, double zp, double h) {
          if (m && p) return (zp - zm) / (2 * h);
          if (p) return (zp - z0) / h;
          if (m) return (z0 - zm) / h;
          return kNaN;
        };
        if (!z.valid(j, i)) continue;
        const bool xm = i > 0 && z.valid(j, i - 1), xp = i + 1 < nx && z.valid(j, i + 1);
        const bool ym = j > 0 && z.valid(j - 1, i), yp = j + 1 < ny && z.valid(j + 1, i);
        gx.z_mm(j, i) = d(xm, xp, xm ? z.z_mm(j, i - 1) : 0, z.z_mm(j, i), xp ? z.z_mm(j, i + 1) : 0, z.dx_mm);
        gy.z_mm(j, i) = d(ym, yp, ym ? z.z_mm(j - 1, i) : 0, z.z_mm(j, i), yp ? z.z_mm(j + 1, i) : 0, z.dy_mm);
      }
  }
  // Height and unit normal at (x, y); false off the surface.
  bool eval(double x, double y, double& f, Eigen::Vector3d& n) const {
    double a, b;
    if (!sample_bilinear(z, x, y, f) || !sample_bilinear(gx, x, y, a) || !sample_bilinear(gy, x, y, b)) return false;
    n = Eigen::Vector3d(-a, -b, 1.0).normalized();
    return true;
  }
};

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// One linearisation: residuals at the current transform, and the weighted normal equations.
struct Linearisation {
  std::size_t points = 0, inliers = 0;
  double sigma = 0, rms = 0, mean = 0;
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
};

Linearisation linearise(const std::vector<Eigen::Vector3d>& pts, const Target& target, const RigidTransform& T,
                        const std::vector<Region>& regions, RobustLoss loss, double tuning) {
  const std::size_t n = pts.size();
  std::vector<double> r(n, kNaN);
  std::vector<Eigen::Vector3d> q(n), nrm(n);
#pragma omp parallel for schedule(static)
  for (std::size_t k = 0; k < n; ++k) {
    q[k] = T.apply(pts[k]);
    if (!regions.empty() &&
        std::none_of(regions.begin(), regions.end(), [&](const Region& R) { return R.contains(q[k].x(), q[k].y()); }))
      continue;
    double f;
    if (!target.eval(q[k].x(), q[k].y(), f, nrm[k])) continue;
    r[k] = (q[k].z() - f) * nrm[k].z();  // vertical gap times cos(slope): the distance to the tangent plane
  }
  Linearisation L;
  std::vector<double> rv;
  rv.reserve(n);
  for (std::size_t k = 0; k < n; ++k)
    if (std::isfinite(r[k])) rv.push_back(r[k]), L.centre += q[k];
  L.points = rv.size();
  if (L.points < 6) return L;
  L.centre /= static_cast<double>(L.points);
  const double med = median_of(rv);
  for (double& x : rv) x = std::abs(x - med);
  // Scale floor 10 nm: a noise-free synthetic case would otherwise shrink the scale to rounding and drop points.
  L.sigma = std::max(1.4826 * median_of(rv), 1e-5);
  const double c = tuning * L.sigma;
  const auto weight = [&](double x) {
    const double a = std::abs(x);
    switch (loss) {
      case RobustLoss::None:
        return 1.0;
      case RobustLoss::Huber:
        return a <= c ? 1.0 : c / a;
      case RobustLoss::Tukey: {
        if (a >= c) return 0.0;
        const double u = 1 - (x / c) * (x / c);
        return u * u;
      }
    }
    return 1.0;
  };
  // Block sums in parallel, added in block order: the result does not depend on the thread count.
  constexpr std::size_t kBlock = 2048;
  const std::size_t nb = (n + kBlock - 1) / kBlock;
  struct Acc {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double w = 0, wr = 0, wr2 = 0;
    std::size_t in = 0;
  };
  std::vector<Acc> acc(nb);
#pragma omp parallel for schedule(static)
  for (std::size_t b = 0; b < nb; ++b) {
    Acc a;
    for (std::size_t k = b * kBlock; k < std::min(n, (b + 1) * kBlock); ++k) {
      if (!std::isfinite(r[k])) continue;
      const double w = weight(r[k]);
      if (w <= 0) continue;
      Eigen::Matrix<double, 6, 1> J;
      J.head<3>() = (q[k] - L.centre).cross(nrm[k]);
      J.tail<3>() = nrm[k];
      a.H.noalias() += w * J * J.transpose();
      a.g.noalias() += w * r[k] * J;
      a.w += w, a.wr += w * r[k], a.wr2 += w * r[k] * r[k];
      ++a.in;
    }
    acc[b] = a;
  }
  double w = 0, wr = 0, wr2 = 0;
  for (const Acc& a : acc) L.H += a.H, L.g += a.g, w += a.w, wr += a.wr, wr2 += a.wr2, L.inliers += a.in;
  L.mean = w > 0 ? wr / w : 0;
  L.rms = w > 0 ? std::sqrt(wr2 / w) : 0;
  return L;
}

struct Step {
  RigidTransform T;
  double rot = 0, trans = 0;
  std::vector<int> weak;
};

// Solves the normal equations in scaled coordinates (rotations times the points' RMS radius, so all six are
// lengths), leaving out directions the data do not constrain; composes the increment on the left about the centre.
Step solve_step(const Linearisation& L, const RigidTransform& T, double radius) {
  Eigen::Matrix<double, 6, 1> D;
  D << radius, radius, radius, 1, 1, 1;
  const Eigen::Matrix<double, 6, 6> Hs = D.asDiagonal().inverse() * L.H * D.asDiagonal().inverse();
  const Eigen::Matrix<double, 6, 1> gs = D.asDiagonal().inverse() * L.g;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(Hs);
  const double top = es.eigenvalues().maxCoeff();
  Eigen::Matrix<double, 6, 1> ds = Eigen::Matrix<double, 6, 1>::Zero();
  Step s;
  for (int k = 0; k < 6; ++k) {
    const double lam = es.eigenvalues()[k];
    const auto v = es.eigenvectors().col(k);
    if (!(lam > 1e-9 * top)) {  // unconstrained: hold
      int dom = 0;
      v.cwiseAbs().maxCoeff(&dom);
      s.weak.push_back(dom);
      continue;
    }
    ds -= (v.dot(gs) / lam) * v;
  }
  const Eigen::Matrix<double, 6, 1> d = D.asDiagonal().inverse() * ds;
  const Eigen::Vector3d w = d.head<3>(), v = d.tail<3>();
  Eigen::Matrix3d Rd = Eigen::Matrix3d::Identity();
  if (w.norm() > 0) Rd = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  // q' = Rd (q - c) + c + v, q = R p + t.
  s.T.R = Rd * T.R;
  s.T.t = Rd * (T.t - L.centre) + L.centre + v;
  // Orthonormalise against drift over many compositions.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(s.T.R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  s.T.R = svd.matrixU() * svd.matrixV().transpose();
  s.rot = w.norm();
  s.trans = v.norm();
  return s;
}

}  // namespace

RegistrationResult register_scan(const core::HeightGrid& scan, const core::HeightGrid& pred,
                                 const RegistrationOptions& o) {
  if (scan.nx() < 2 || scan.ny() < 2 || pred.nx() < 2 || pred.ny() < 2)
    throw core::Error("registration: both surfaces need at least 2 x 2 points");
  // The scan's points: valid nodes on a regular subsample.
  std::size_t valid = 0;
  for (Eigen::Index k = 0; k < scan.z_mm.size(); ++k) valid += std::isfinite(scan.z_mm.data()[k]) ? 1 : 0;
  const Eigen::Index stride = std::max<Eigen::Index>(
      1, static_cast<Eigen::Index>(std::ceil(
             std::sqrt(static_cast<double>(valid) / static_cast<double>(std::max<std::size_t>(o.max_points, 16))))));
  std::vector<std::pair<Eigen::Index, Eigen::Index>> nodes;
  for (Eigen::Index j = 0; j < scan.ny(); j += stride)
    for (Eigen::Index i = 0; i < scan.nx(); i += stride)
      if (scan.valid(j, i)) nodes.emplace_back(j, i);
  const auto points_of = [&](const core::HeightGrid& s) {
    std::vector<Eigen::Vector3d> p;
    p.reserve(nodes.size());
    for (const auto& [j, i] : nodes)
      if (s.valid(j, i)) p.emplace_back(s.x(i), s.y(j), s.z_mm(j, i));
    return p;
  };

  RegistrationResult res;
  RigidTransform T;
  if (o.initial) {
    T = *o.initial;
    res.initial_guess = "given";
  } else {
    // Tilt: make the scan's least-squares plane parallel to the prediction's.
    const FormFit fs = fit_form(scan, 1), fp = fit_form(pred, 1);
    const Eigen::Vector3d ns = Eigen::Vector3d(-fs.slope_x, -fs.slope_y, 1).normalized();
    const Eigen::Vector3d np = Eigen::Vector3d(-fp.slope_x, -fp.slope_y, 1).normalized();
    const Eigen::Matrix3d R0 = Eigen::Quaterniond::FromTwoVectors(ns, np).toRotationMatrix();
    const Eigen::Vector3d cs(fs.x_centre_mm, fs.y_centre_mm, fs.z_centre_mm);
    // Footprint: keep x/y when at least half of the scan's extent lies on the prediction.
    const double sx0 = scan.x0_mm, sx1 = scan.x(scan.nx() - 1), sy0 = scan.y0_mm, sy1 = scan.y(scan.ny() - 1);
    const double px0 = pred.x0_mm, px1 = pred.x(pred.nx() - 1), py0 = pred.y0_mm, py1 = pred.y(pred.ny() - 1);
    const double ox = std::max(0.0, std::min(sx1, px1) - std::max(sx0, px0)),
                 oy = std::max(0.0, std::min(sy1, py1) - std::max(sy0, py0));
    const bool overlap = ox * oy >= 0.5 * (sx1 - sx0) * (sy1 - sy0);
    const Eigen::Vector3d target_centre = overlap ? cs : Eigen::Vector3d(fp.x_centre_mm, fp.y_centre_mm, cs.z());
    T.R = R0;
    T.t = target_centre - R0 * cs;
    res.initial_guess =
        std::string("plane-parallel tilt, ") + (overlap ? "x/y as scanned" : "scan centre on the prediction's centre");
    // Height: the median gap over the points that land on the prediction.
    const Target tgt(pred);
    std::vector<double> gaps;
    for (const Eigen::Vector3d& p : points_of(scan)) {
      const Eigen::Vector3d q = T.apply(p);
      double f;
      Eigen::Vector3d n;
      if (tgt.eval(q.x(), q.y(), f, n)) gaps.push_back(f - q.z());
    }
    if (gaps.size() < 6)
      throw core::Error(
          "registration: the initial guess puts fewer than 6 scan points on the prediction; give an initial transform");
    T.t.z() += median_of(gaps);
    res.initial_guess += ", z from the median height difference";
  }

  // Levels: Gaussian cut-offs in grid steps, then the raw surfaces.
  const double h = std::max({pred.dx_mm, pred.dy_mm, scan.dx_mm, scan.dy_mm});
  std::vector<double> levels;
  if (o.coarse_to_fine) levels = {32 * h, 8 * h};
  levels.push_back(0);
  std::vector<int> weak_final;
  for (std::size_t lv = 0; lv < levels.size(); ++lv) {
    const bool last = lv + 1 == levels.size();
    const Target tgt(levels[lv] > 0 ? gaussian_mean_surface(pred, levels[lv]) : pred);
    const std::vector<Eigen::Vector3d> pts = points_of(levels[lv] > 0 ? gaussian_mean_surface(scan, levels[lv]) : scan);
    // RMS radius about the centroid, to scale rotations into lengths.
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : pts) c += p;
    c /= static_cast<double>(std::max<std::size_t>(pts.size(), 1));
    double rad = 0;
    for (const auto& p : pts) rad += (p - c).squaredNorm();
    rad = std::max(std::sqrt(rad / static_cast<double>(std::max<std::size_t>(pts.size(), 1))), h);
    // Huber first (convex, forgiving of a rough start), then the chosen loss on the last level.
    const std::vector<std::pair<RobustLoss, double>> phases =
        last && o.loss != RobustLoss::Huber
            ? std::vector<std::pair<RobustLoss, double>>{{RobustLoss::Huber, 1.345}, {o.loss, o.tuning}}
            : std::vector<std::pair<RobustLoss, double>>{
                  {RobustLoss::Huber, o.loss == RobustLoss::Huber ? o.tuning : 1.345}};
    for (const auto& [loss, tuning] : phases) {
      bool done = false;
      for (int it = 0; it < o.max_iterations && !done; ++it) {
        const Linearisation L = linearise(pts, tgt, T, o.regions, loss, tuning);
        if (L.points < 6)
          throw core::Error(
              fmt::format("registration: only {} scan points fall on the prediction{}; check the initial "
                          "transform or the regions",
                          L.points, o.regions.empty() ? "" : " inside the regions"));
        const Step s = solve_step(L, T, rad);
        T = s.T;
        ++res.iterations;
        weak_final = s.weak;
        // Converged when the step moves no point by more than 0.1 nm (rotation times radius): far below any
        // scan's noise, and above the jitter of points entering and leaving the overlap from one step to the next.
        done = s.rot * rad + s.trans < 1e-7;
      }
      res.converged = done;
    }
  }
  res.transform = T;
  const Target tgt(pred);
  const Linearisation L = linearise(points_of(scan), tgt, T, o.regions, o.loss, o.tuning);
  res.points = L.points, res.inliers = L.inliers, res.rms_mm = L.rms, res.mean_mm = L.mean,
  res.robust_sigma_mm = L.sigma;
  std::sort(weak_final.begin(), weak_final.end());
  weak_final.erase(std::unique(weak_final.begin(), weak_final.end()), weak_final.end());
  for (int d : weak_final) res.weak_directions.emplace_back(kDirection[d]);
  return res;
}

core::HeightGrid resample_scan(const core::HeightGrid& scan, const RigidTransform& T, const core::HeightGrid& target) {
  core::HeightGrid out = target;
  const Eigen::Index nx = target.nx(), ny = target.ny();
  const RigidTransform inv = T.inverse();
  const Eigen::Matrix2d Rxy = T.R.topLeftCorner<2, 2>();
  const Eigen::Vector2d Rz = T.R.topRightCorner<2, 1>();
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j)
    for (Eigen::Index i = 0; i < nx; ++i) {
      const double X = target.x(i), Y = target.y(j);
      const double zguess = std::isfinite(target.z_mm(j, i)) ? target.z_mm(j, i) : T.t.z();
      Eigen::Vector3d p = inv.apply(Eigen::Vector3d(X, Y, zguess));
      double result = kNaN;
      for (int it = 0; it < 12; ++it) {
        double hgt, gx, gy;
        if (!sample_bilinear(scan, p.x(), p.y(), hgt, &gx, &gy)) break;
        const Eigen::Vector3d P = T.apply(Eigen::Vector3d(p.x(), p.y(), hgt));
        const Eigen::Vector2d e(X - P.x(), Y - P.y());
        if (e.norm() < 1e-10) {
          result = P.z();
          break;
        }
        const Eigen::Matrix2d A = Rxy + Rz * Eigen::RowVector2d(gx, gy);
        const Eigen::Vector2d d = A.inverse() * e;
        p.x() += d.x(), p.y() += d.y();
      }
      out.z_mm(j, i) = result;
    }
  return out;
}

}  // namespace vmsim::metrology
