#include "removal/dexel_grid.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr Interval kEmpty{1.0f, -1.0f};
}  // namespace

IntervalStore::IntervalStore(std::size_t rays, std::size_t rays_per_row)
    : per_row_(std::max<std::size_t>(1, rays_per_row)),
      head_(rays, kEmpty),
      overflow_((rays + per_row_ - 1) / per_row_ + 1) {}

void IntervalStore::fill(double lo, double hi) {
  std::fill(head_.begin(), head_.end(), Interval{static_cast<float>(lo), static_cast<float>(hi)});
  for (auto& row : overflow_) row.clear();
}

void IntervalStore::set(std::size_t ray, const std::vector<Interval>& iv) {
  Interval& h = head_[ray];
  if (std::isnan(h.lo)) row_of(ray).erase(ray);
  if (iv.empty()) {
    h = kEmpty;
  } else if (iv.size() == 1) {
    h = iv.front();
  } else {
    h = Interval{kNaN, kNaN};
    row_of(ray)[ray] = iv;
  }
}

void IntervalStore::get(std::size_t ray, std::vector<Interval>& out) const {
  out.clear();
  const Interval& h = head_[ray];
  if (std::isnan(h.lo)) {
    out = row_of(ray).at(ray);
  } else if (!is_empty(h)) {
    out.push_back(h);
  }
}

double IntervalStore::top_several(std::size_t ray) const { return row_of(ray).at(ray).back().hi; }

double IntervalStore::bottom_several(std::size_t ray) const { return row_of(ray).at(ray).front().lo; }

void IntervalStore::split(std::size_t ray, double t0, double t1) {
  Interval& h = head_[ray];
  const Interval lowp{h.lo, static_cast<float>(t0)}, highp{static_cast<float>(t1), h.hi};
  h = Interval{kNaN, kNaN};
  row_of(ray)[ray] = {lowp, highp};
}

void IntervalStore::subtract_several(std::size_t ray, double t0, double t1) {
  auto& row = row_of(ray);
  std::vector<Interval>& iv = row.at(ray);
  // Nothing to remove (a sweep passing beside the material): leave the list as it is.
  if (std::none_of(iv.begin(), iv.end(), [&](const Interval& x) { return !(t1 <= x.lo || t0 >= x.hi); })) return;
  // Rebuild the list without [t0, t1].
  std::vector<Interval> out;
  out.reserve(iv.size() + 1);
  for (const Interval& x : iv) {
    if (t1 <= x.lo || t0 >= x.hi) {
      out.push_back(x);
      continue;
    }
    if (t0 > x.lo) out.push_back({x.lo, static_cast<float>(t0)});
    if (t1 < x.hi) out.push_back({static_cast<float>(t1), x.hi});
  }
  if (out.size() <= 1) {
    row.erase(ray);
    head_[ray] = out.empty() ? kEmpty : out.front();
  } else {
    iv.swap(out);
  }
}

std::size_t IntervalStore::memory_bytes() const {
  std::size_t b = head_.capacity() * sizeof(Interval) + overflow_.capacity() * sizeof(overflow_[0]);
  for (const auto& row : overflow_)
    for (const auto& [k, v] : row) b += sizeof(k) + sizeof(v) + 2 * sizeof(void*) + v.capacity() * sizeof(Interval);
  return b;
}

std::size_t IntervalStore::initial_bytes(std::size_t rays, std::size_t rays_per_row) {
  const std::size_t per_row = std::max<std::size_t>(1, rays_per_row);
  return rays * sizeof(Interval) + ((rays + per_row - 1) / per_row + 1) * sizeof(overflow_[0]);
}

std::size_t IntervalStore::interval_count() const {
  std::size_t n = 0;
  for (const Interval& h : head_) n += !std::isnan(h.lo) && !is_empty(h);
  for (const auto& row : overflow_)
    for (const auto& [k, v] : row) n += v.size();
  return n;
}

DexelGrid::DexelGrid(const Eigen::Vector3d& origin, const Eigen::Vector3d& U, const Eigen::Vector3d& V, double du,
                     double dv, int nu, int nv, double length, int v_first)
    : origin_(origin),
      U_(U.normalized()),
      V_(V.normalized()),
      W_(U.normalized().cross(V.normalized())),
      du_(du),
      dv_(dv),
      length_(length),
      nu_(nu),
      nv_(nv),
      v_first_(v_first) {
  if (nu <= 0 || nv <= 0 || !(du > 0) || !(dv > 0) || !(length > 0) || v_first < 0)
    throw core::Error("dexel grid: expected positive sizes and spacings");
  store_ = IntervalStore(static_cast<std::size_t>(nu) * static_cast<std::size_t>(nv), static_cast<std::size_t>(nu));
}

NeedleSet::NeedleSet(std::vector<Eigen::Vector3d> origin, std::vector<Eigen::Vector3d> direction,
                     std::vector<double> length)
    : origin_(std::move(origin)), dir_(std::move(direction)), length_(std::move(length)) {
  if (origin_.size() != dir_.size() || origin_.size() != length_.size())
    throw core::Error("needle set: origins, directions and lengths differ in number");
  for (auto& d : dir_) d.normalize();
  store_ = IntervalStore(origin_.size(), kBlock);
}

}  // namespace vmsim::removal
