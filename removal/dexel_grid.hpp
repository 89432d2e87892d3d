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

#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

namespace vmsim::removal {

struct Interval {
  float lo, hi;
};

// Material intervals of a set of rays: one interval per ray in place (8 bytes), more in a per-row overflow table.
// Rays are grouped in rows; concurrent updates of different rows are safe.
class IntervalStore {
 public:
  IntervalStore() = default;
  IntervalStore(std::size_t rays, std::size_t rays_per_row);
  std::size_t size() const { return head_.size(); }

  void fill(double lo, double hi);
  void set(std::size_t ray, const std::vector<Interval>& iv);
  void get(std::size_t ray, std::vector<Interval>& out) const;  // sorted, disjoint
  // Highest material point, NaN when empty. The one-interval case (nearly every ray) inline.
  double top(std::size_t ray) const {
    const Interval& h = head_[ray];
    if (std::isnan(h.lo)) return top_several(ray);
    return is_empty(h) ? std::numeric_limits<double>::quiet_NaN() : h.hi;
  }
  // Lowest material point, NaN when empty.
  double bottom(std::size_t ray) const {
    const Interval& h = head_[ray];
    if (std::isnan(h.lo)) return bottom_several(ray);
    return is_empty(h) ? std::numeric_limits<double>::quiet_NaN() : h.lo;
  }
  // The in-place intervals (hot loops read them directly; lo = NaN marks a ray with several intervals). A hot loop may
  // rewrite a ray that holds one interval (or none) in place with one interval or none (lo > hi), never with more.
  const Interval* head() const { return head_.data(); }
  Interval* head() { return head_.data(); }
  // Removes [t0, t1] from a ray. The one-interval case inline unless the cut splits it.
  void subtract(std::size_t ray, double t0, double t1) {
    Interval& h = head_[ray];
    if (std::isnan(h.lo)) return subtract_several(ray, t0, t1);
    if (is_empty(h) || t1 <= h.lo || t0 >= h.hi) return;
    const bool keep_low = t0 > h.lo, keep_high = t1 < h.hi;
    if (keep_low && keep_high) return split(ray, t0, t1);
    if (keep_low) {
      h.hi = static_cast<float>(t0);
    } else if (keep_high) {
      h.lo = static_cast<float>(t1);
    } else {
      h = Interval{1.0f, -1.0f};  // empty
    }
  }
  std::size_t memory_bytes() const;
  std::size_t interval_count() const;
  // memory_bytes() of a store of this size before any cut splits a ray (memory plans, app/run_plan.hpp).
  static std::size_t initial_bytes(std::size_t rays, std::size_t rays_per_row);

 private:
  static bool is_empty(const Interval& h) { return !(h.lo <= h.hi); }
  double top_several(std::size_t ray) const;
  double bottom_several(std::size_t ray) const;
  void subtract_several(std::size_t ray, double t0, double t1);
  void split(std::size_t ray, double t0, double t1);
  std::unordered_map<std::size_t, std::vector<Interval>>& row_of(std::size_t ray) { return overflow_[ray / per_row_]; }
  const std::unordered_map<std::size_t, std::vector<Interval>>& row_of(std::size_t ray) const {
    return overflow_[ray / per_row_];
  }
  std::size_t per_row_ = 1;
  // lo = NaN: the ray's intervals are in the overflow table; lo > hi: empty.
  std::vector<Interval> head_;
  std::vector<std::unordered_map<std::size_t, std::vector<Interval>>> overflow_;
};

class DexelGrid {
 public:
  DexelGrid() = default;
  // Rays start at origin + i du U + (v_first + j) dv V, i < nu, j < nv, and run along W = U x V over [0, length_mm].
  // v_first > 0 makes the grid a window of rows of a larger one (a tile of a tiled run): same origin, same lattice,
  // so every ray's position, and every cut computed from it, is bit-identical to the larger grid's.
  DexelGrid(const Eigen::Vector3d& origin, const Eigen::Vector3d& U, const Eigen::Vector3d& V, double du_mm,
            double dv_mm, int nu, int nv, double length_mm, int v_first = 0);

  int nu() const { return nu_; }
  int nv() const { return nv_; }
  double du() const { return du_; }
  double dv() const { return dv_; }
  double length() const { return length_; }
  int v_first() const { return v_first_; }                   // lattice row of row 0
  double v_of(int j) const { return (v_first_ + j) * dv_; }  // row j's offset along V from the origin
  const Eigen::Vector3d& origin() const { return origin_; }
  const Eigen::Vector3d& U() const { return U_; }
  const Eigen::Vector3d& V() const { return V_; }
  const Eigen::Vector3d& W() const { return W_; }
  Eigen::Vector3d ray_origin(int i, int j) const { return origin_ + (i * du_) * U_ + ((v_first_ + j) * dv_) * V_; }
  std::size_t ray(int i, int j) const { return static_cast<std::size_t>(j) * static_cast<std::size_t>(nu_) + i; }

  // Every ray full over [lo, hi] (ray parameters).
  void fill(double lo, double hi) { store_.fill(lo, hi); }
  void set_intervals(int i, int j, const std::vector<Interval>& iv) { store_.set(ray(i, j), iv); }
  void intervals(int i, int j, std::vector<Interval>& out) const { store_.get(ray(i, j), out); }
  double top(int i, int j) const { return store_.top(ray(i, j)); }
  double bottom(int i, int j) const { return store_.bottom(ray(i, j)); }
  // Row j's in-place intervals (IntervalStore::head: a hot loop may rewrite a one-interval ray in place).
  const Interval* head_row(int j) const {
    return store_.head() + static_cast<std::size_t>(j) * static_cast<std::size_t>(nu_);
  }
  Interval* head_row(int j) { return store_.head() + static_cast<std::size_t>(j) * static_cast<std::size_t>(nu_); }
  // Removes [t0, t1] from a ray. Rows may be updated concurrently; one row must not.
  void subtract(int i, int j, double t0, double t1) { store_.subtract(ray(i, j), t0, t1); }

  std::size_t memory_bytes() const { return store_.memory_bytes(); }
  std::size_t interval_count() const { return store_.interval_count(); }

 private:
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero(), U_ = Eigen::Vector3d::UnitX(), V_ = Eigen::Vector3d::UnitY(),
                  W_ = Eigen::Vector3d::UnitZ();
  double du_ = 1, dv_ = 1, length_ = 0;
  int nu_ = 0, nv_ = 0, v_first_ = 0;
  IntervalStore store_;
};

// Needles: rays at chosen points along chosen directions (the feed-drive simulation paper's N-buffer: normals of the
// nominal surface, or the rays of a measurement grid). Needle k runs from origin[k] along direction[k] over [0,
// length[k]].
class NeedleSet {
 public:
  NeedleSet() = default;
  NeedleSet(std::vector<Eigen::Vector3d> origin, std::vector<Eigen::Vector3d> direction, std::vector<double> length);
  std::size_t size() const { return origin_.size(); }
  const Eigen::Vector3d& origin(std::size_t k) const { return origin_[k]; }
  const Eigen::Vector3d& direction(std::size_t k) const { return dir_[k]; }
  double length(std::size_t k) const { return length_[k]; }
  IntervalStore& store() { return store_; }
  const IntervalStore& store() const { return store_; }
  static constexpr std::size_t kBlock = 64;  // needles per row of the store (a work item)

 private:
  std::vector<Eigen::Vector3d> origin_, dir_;
  std::vector<double> length_;
  IntervalStore store_;
};

}  // namespace vmsim::removal
