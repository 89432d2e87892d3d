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

DexelGrid::DexelGrid(const Eigen::Vector3d& origin, const Eigen::Vector3d& U, const Eigen::Vector3d& V, double du,
                     double dv, int nu, int nv, double length)
    : origin_(origin), U_(U.normalized()), V_(V.normalized()), W_(U.normalized().cross(V.normalized())), du_(du),
      dv_(dv), length_(length), nu_(nu), nv_(nv) {
  if (nu <= 0 || nv <= 0 || !(du > 0) || !(dv > 0) || !(length > 0))
    throw core::Error("dexel grid: expected positive sizes and spacings");
  head_.assign(static_cast<std::size_t>(nu) * static_cast<std::size_t>(nv), kEmpty);
  overflow_.resize(static_cast<std::size_t>(nv));
}

void DexelGrid::fill(double lo, double hi) {
  std::fill(head_.begin(), head_.end(), Interval{static_cast<float>(lo), static_cast<float>(hi)});
  for (auto& row : overflow_) row.clear();
}

std::vector<Interval>& DexelGrid::spill(int i, int j) { return overflow_[static_cast<std::size_t>(j)][i]; }

void DexelGrid::set_intervals(int i, int j, const std::vector<Interval>& iv) {
  Interval& h = head_[static_cast<std::size_t>(j) * nu_ + i];
  if (std::isnan(h.lo)) overflow_[static_cast<std::size_t>(j)].erase(i);
  if (iv.empty()) {
    h = kEmpty;
  } else if (iv.size() == 1) {
    h = iv.front();
  } else {
    h = Interval{kNaN, kNaN};
    spill(i, j) = iv;
  }
}

void DexelGrid::intervals(int i, int j, std::vector<Interval>& out) const {
  out.clear();
  const Interval& h = head_[static_cast<std::size_t>(j) * nu_ + i];
  if (std::isnan(h.lo)) {
    const auto& row = overflow_[static_cast<std::size_t>(j)];
    out = row.at(i);
  } else if (!is_empty(h)) {
    out.push_back(h);
  }
}

double DexelGrid::top(int i, int j) const {
  const Interval& h = head_[static_cast<std::size_t>(j) * nu_ + i];
  if (std::isnan(h.lo)) return overflow_[static_cast<std::size_t>(j)].at(i).back().hi;
  if (is_empty(h)) return std::numeric_limits<double>::quiet_NaN();
  return h.hi;
}

void DexelGrid::subtract(int i, int j, double t0, double t1) {
  Interval& h = head_[static_cast<std::size_t>(j) * nu_ + i];
  if (!std::isnan(h.lo)) {
    if (is_empty(h) || t1 <= h.lo || t0 >= h.hi) return;
    const bool keep_low = t0 > h.lo, keep_high = t1 < h.hi;
    if (keep_low && keep_high) {  // the cut splits the interval
      const Interval lowp{h.lo, static_cast<float>(t0)}, highp{static_cast<float>(t1), h.hi};
      h = Interval{kNaN, kNaN};
      spill(i, j) = {lowp, highp};
    } else if (keep_low) {
      h.hi = static_cast<float>(t0);
    } else if (keep_high) {
      h.lo = static_cast<float>(t1);
    } else {
      h = kEmpty;
    }
    return;
  }
  // Several intervals: rebuild the list without [t0, t1].
  auto& row = overflow_[static_cast<std::size_t>(j)];
  std::vector<Interval>& iv = row.at(i);
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
    row.erase(i);
    h = out.empty() ? kEmpty : out.front();
  } else {
    iv.swap(out);
  }
}

std::size_t DexelGrid::memory_bytes() const {
  std::size_t b = head_.capacity() * sizeof(Interval) + overflow_.capacity() * sizeof(overflow_[0]);
  for (const auto& row : overflow_)
    for (const auto& [k, v] : row) b += sizeof(k) + sizeof(v) + 2 * sizeof(void*) + v.capacity() * sizeof(Interval);
  return b;
}

std::size_t DexelGrid::interval_count() const {
  std::size_t n = 0;
  for (const Interval& h : head_) n += !std::isnan(h.lo) && !is_empty(h);
  for (const auto& row : overflow_)
    for (const auto& [k, v] : row) n += v.size();
  return n;
}

}  // namespace vmsim::removal
