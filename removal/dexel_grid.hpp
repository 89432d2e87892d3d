#pragma once
// A grid of parallel rays (dexels), each holding the sorted intervals of material along it: a z-map is one grid
// along +Z; a tri-dexel field is three grids along X, Y and Z.
//
// Memory: a ray with one interval (the common case) costs 8 bytes (two floats, offsets in mm from the ray's
// start: 0.008 um resolution over 100 mm); rays that a cut splits keep their intervals in a per-row overflow
// table. Updates of different rows never touch the same memory, so rows are processed in parallel without locks
// and the result is the same for any thread count (interval subtraction is order-independent and exact in the
// float positions it stores).
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <unordered_map>
#include <vector>

namespace vmsim::removal {

struct Interval {
  float lo, hi;
};

class DexelGrid {
 public:
  DexelGrid() = default;
  // Rays start at origin + i du U + j dv V, i < nu, j < nv, and run along W = U x V over [0, length_mm].
  DexelGrid(const Eigen::Vector3d& origin, const Eigen::Vector3d& U, const Eigen::Vector3d& V, double du_mm,
            double dv_mm, int nu, int nv, double length_mm);

  int nu() const { return nu_; }
  int nv() const { return nv_; }
  double du() const { return du_; }
  double dv() const { return dv_; }
  double length() const { return length_; }
  const Eigen::Vector3d& origin() const { return origin_; }
  const Eigen::Vector3d& U() const { return U_; }
  const Eigen::Vector3d& V() const { return V_; }
  const Eigen::Vector3d& W() const { return W_; }
  Eigen::Vector3d ray_origin(int i, int j) const { return origin_ + (i * du_) * U_ + (j * dv_) * V_; }

  // Every ray full over [lo, hi] (ray parameters).
  void fill(double lo, double hi);
  void set_intervals(int i, int j, const std::vector<Interval>& iv);
  // The material intervals of a ray, sorted, disjoint.
  void intervals(int i, int j, std::vector<Interval>& out) const;
  // Highest material point along the ray (the part's surface seen against the ray), or NaN when empty.
  double top(int i, int j) const;
  // Removes [t0, t1] from a ray. Rows may be updated concurrently; one row must not.
  void subtract(int i, int j, double t0, double t1);

  std::size_t memory_bytes() const;
  std::size_t interval_count() const;

 private:
  static bool is_empty(const Interval& h) { return !(h.lo <= h.hi); }
  std::vector<Interval>& spill(int i, int j);

  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero(), U_ = Eigen::Vector3d::UnitX(), V_ = Eigen::Vector3d::UnitY(),
                  W_ = Eigen::Vector3d::UnitZ();
  double du_ = 1, dv_ = 1, length_ = 0;
  int nu_ = 0, nv_ = 0;
  // One interval per ray in place. lo = NaN: the ray's intervals are in overflow_[j][i]; lo > hi: empty.
  std::vector<Interval> head_;
  std::vector<std::unordered_map<int, std::vector<Interval>>> overflow_;
};

}  // namespace vmsim::removal
