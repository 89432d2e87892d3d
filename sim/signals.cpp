#include "sim/signals.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"
#include "motion/kinematics.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vmsim::sim {

namespace {

using core::units::kNaN;

// An axis' columns after its setpoint's (SignalBinner::AxisColumns::first): the setpoint, tracking error and the
// setpoint's three differences; the drive's position, velocity, acceleration, jerk, mean and peak current.
constexpr int kSetpointColumn[5] = {0, 2, 3, 5, 7};
constexpr int kDriveColumn[6] = {1, 4, 6, 8, 9, 10};

// A cell: 7 significant digits, "nan" where undefined (core::append_general: the bytes fmt's "{:.7g}" wrote).
void append_cell(std::string& line, double v) {
  if (std::isfinite(v))
    core::append_general(line, v, 7);
  else
    line += "nan";
}

}  // namespace

namespace {

// The smallest and largest of v[0, n) (times f when Scaled) and whether all are finite, two rows per instruction in
// two interleaved chains (issue 21: the fold in row order, a min, a max and a finiteness sum per value and column,
// was most of the binner's time). Any order gives the same value for both ends; only the sign of a zero end can
// depend on it (min(+0, -0) keeps the first), which fold_column settles. A non-finite value makes the sum of v * 0
// NaN.
template <bool Scaled>
inline void packed_range(const double* v, Eigen::Index n, double f, double& lo, double& hi, bool& finite) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double l = kInf, h = -kInf, z = 0.0;
  Eigen::Index i = 0;
#if defined(__SSE2__)
  {
    const __m128d vf = _mm_set1_pd(f), zero = _mm_setzero_pd();
    __m128d l0 = _mm_set1_pd(kInf), l1 = l0, h0 = _mm_set1_pd(-kInf), h1 = h0, z0 = zero, z1 = zero;
    for (; i + 4 <= n; i += 4) {
      __m128d x0 = _mm_loadu_pd(v + i), x1 = _mm_loadu_pd(v + i + 2);
      if constexpr (Scaled) x0 = _mm_mul_pd(x0, vf), x1 = _mm_mul_pd(x1, vf);
      l0 = _mm_min_pd(l0, x0), l1 = _mm_min_pd(l1, x1);
      h0 = _mm_max_pd(h0, x0), h1 = _mm_max_pd(h1, x1);
      z0 = _mm_add_pd(z0, _mm_mul_pd(x0, zero)), z1 = _mm_add_pd(z1, _mm_mul_pd(x1, zero));
    }
    double lv[2], hv[2], zv[2];
    _mm_storeu_pd(lv, _mm_min_pd(l0, l1));
    _mm_storeu_pd(hv, _mm_max_pd(h0, h1));
    _mm_storeu_pd(zv, _mm_add_pd(z0, z1));
    l = std::min(lv[0], lv[1]), h = std::max(hv[0], hv[1]), z = zv[0] + zv[1];
  }
#endif
  for (; i < n; ++i) {
    const double x = Scaled ? v[i] * f : v[i];
    l = std::min(l, x), h = std::max(h, x), z += x * 0.0;
  }
  lo = l, hi = h, finite = z == 0.0;
}

}  // namespace

int BinnedSignals::find(const std::string& name) const {
  for (std::size_t k = 0; k < names.size(); ++k)
    if (names[k] == name) return static_cast<int>(k);
  return -1;
}

std::optional<double> BinnedSignals::limit(const std::string& name) const {
  const auto it = limits.find(name);
  if (it == limits.end()) return std::nullopt;
  return it->second;
}

SignalBinner::SignalBinner(const core::Job& job, const core::ToolPath& program, const core::Setpoints& sp,
                           Eigen::Index rows, double feed_scale, Eigen::Index max_bins)
    : job_(&job), program_(&program), sp_(&sp), n_(rows), ns_(sp.samples()), feed_scale_(feed_scale) {
  if (n_ == 0 || ns_ == 0) throw core::Error("signals: the run has no samples");
  te_ = sp.period_s;
  bs_ = std::max<Eigen::Index>(1, (n_ + max_bins - 1) / std::max<Eigen::Index>(1, max_bins));
  bins_ = (n_ + bs_ - 1) / bs_;
  kin_ = motion::make_kinematics(job.machine);
  out_.job = job.name;
  out_.period_s = te_;
  const core::Machine& machine = job.machine;
  // The columns in the file's order: t_s, each moving axis's eleven, then the path's.
  column("t_s");
  for (std::size_t a = 0; a < machine.axes.size(); ++a) {
    const core::MachineAxis& ax = machine.axes[a];
    const auto ai = static_cast<Eigen::Index>(a);
    // The column's range in one pass (it is read from memory once, not twice: 3.7 M rows on flower_mold), packed;
    // in order when a value is not finite (std::min and std::max then skip NaN after the first value).
    double lo = sp.position(0, ai), hi = lo;
    bool finite = false;
    packed_range<false>(sp.position.col(ai).data(), ns_, 1.0, lo, hi, finite);
    if (!finite) {
      lo = sp.position(0, ai), hi = lo;
      for (const double x : sp.position.col(ai)) lo = std::min(lo, x), hi = std::max(hi, x);
    }
    const bool moves = hi - lo > 1e-9;
    if (!moves) {
      out_.held_axes.push_back(ax.name);
      continue;
    }
    const bool rotary = ax.kind == core::AxisKind::Rotary;
    const double f = rotary ? core::units::kRadToDeg : 1.0;
    const std::string u = rotary ? "deg" : "mm", A = ax.name;
    out_.axes.emplace_back(A, u);
    axes_.push_back({ai, f, column(A + "_setpoint_" + u)});
    for (const std::string& name :
         {A + "_actual_" + u, A + "_tracking_error_" + u, A + "_velocity_setpoint_" + u + "_per_s",
          A + "_velocity_actual_" + u + "_per_s", A + "_acceleration_setpoint_" + u + "_per_s2",
          A + "_acceleration_actual_" + u + "_per_s2", A + "_jerk_setpoint_" + u + "_per_s3",
          A + "_jerk_actual_" + u + "_per_s3", A + "_current_A", A + "_current_peak_A"})
      column(name);
    out_.limits[A + "_velocity_" + u + "_per_s"] = ax.max_velocity * f;
    out_.limits[A + "_acceleration_" + u + "_per_s2"] = ax.max_acceleration * f;
    out_.limits[A + "_jerk_" + u + "_per_s3"] = ax.max_jerk * f;
    if (ax.drive) out_.limits[A + "_current_A"] = ax.drive->current_limit_A;
  }
  c_feed_ = column("feed_programmed_mm_per_min");
  c_speed_ = column("path_speed_setpoint_mm_per_min");
  c_speed_actual_ = column("path_speed_actual_mm_per_min");
  c_contour_ = column("contour_error_mm");
  c_path_ = column("cutting_path_mm");
  c_cutting_ = column("cutting");
}

SignalBinner::~SignalBinner() = default;

int SignalBinner::column(const std::string& name) {
  out_.names.push_back(name);
  columns_.push_back({Eigen::ArrayXd::Constant(bins_, kNaN), Eigen::ArrayXd::Constant(bins_, kNaN)});
  return static_cast<int>(columns_.size()) - 1;
}

int SignalBinner::move_of(Eigen::Index k) const { return sp_->move_index[std::min(k, ns_ - 1)]; }
bool SignalBinner::cutting(Eigen::Index k) const {
  const int mi = move_of(k);
  return mi >= 0 && !program_->moves[static_cast<std::size_t>(mi)].rapid;
}
double SignalBinner::tlo(Eigen::Index k) const {
  const int mi = move_of(k);
  return mi >= 0 ? program_->moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
}

// Into their bins in row order whatever the blocks (a bin's first finite value starts it; non-finite values are left
// out; std::min / std::max keep the first of equal values). Bin by bin, no division per sample. When a bin's values
// are all finite its packed range decides it: the fold in row order keeps the bin's earlier value when it is not
// beyond the range's end (equal included), and otherwise the first value equal to that end, which has the end's bits
// unless the end is zero (+0 and -0 are equal): then it is the first zero of the bin's values. A bin with a
// non-finite value is folded again in row order with the finiteness test. An empty bin runs from +inf to -inf here.
template <bool Scaled>
void SignalBinner::fold_column(int c, Eigen::Index k0, Eigen::Index r0, Eigen::Index r1, const double* v, double f) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Column& col = columns_[static_cast<std::size_t>(c)];
  Eigen::Index r = r0;
  while (r < r1) {
    const Eigen::Index b = (k0 + r) / bs_;
    const Eigen::Index end = std::min(r1, (b + 1) * bs_ - k0);
    const double* p = v + (r - r0);
    const Eigen::Index len = end - r;
    auto value = [&](Eigen::Index i) { return Scaled ? p[i] * f : p[i]; };
    const bool empty = std::isnan(col.lo[b]);
    double lo = empty ? kInf : col.lo[b], hi = empty ? -kInf : col.hi[b];
    double blo = 0.0, bhi = 0.0;
    bool finite = false;
    packed_range<Scaled>(p, len, f, blo, bhi, finite);
    if (finite) {
      auto first_zero = [&] {
        Eigen::Index i = 0;
        while (value(i) != 0.0) ++i;  // the range's end is zero: some value is
        return value(i);
      };
      if (!(lo <= blo)) lo = blo == 0.0 ? first_zero() : blo;
      if (!(hi >= bhi)) hi = bhi == 0.0 ? first_zero() : bhi;
    } else {
      for (Eigen::Index i = 0; i < len; ++i) {
        const double x = value(i);
        const bool fin = std::isfinite(x);
        lo = std::min(lo, fin ? x : kInf);
        hi = std::max(hi, fin ? x : -kInf);
      }
    }
    const bool none = lo == kInf;  // only finite values enter
    col.lo[b] = none ? kNaN : lo;
    col.hi[b] = none ? kNaN : hi;
    r = end;
  }
}

void SignalBinner::check_block(Eigen::Index k0, Eigen::Index m) const {
  if (k0 != next_ || k0 + m > n_)
    throw core::Error(fmt::format("signals: a block of rows [{}, {}) after row {} of {}", k0, k0 + m, next_, n_));
}

void SignalBinner::add(Eigen::Index k0, const drives::AxisResponse& resp) {
  const Eigen::Index m = resp.samples();
  check_block(k0, m);
  // The tips row by row through forward() (the reference the tips add()'s other form takes are checked against), a
  // few thousand rows at a time.
  constexpr Eigen::Index kChunk = 4096;
  Eigen::MatrixXd act(std::min(m, kChunk), 3), cmd(std::min(m, kChunk), 3);
  for (Eigen::Index r0 = 0; r0 < m; r0 += kChunk) {
    const Eigen::Index r1 = std::min(m, r0 + kChunk);
    for (Eigen::Index r = r0; r < r1; ++r) {
      const Eigen::Index k = k0 + r;
      const double l = tlo(k);
      act.row(r - r0) = kin_->forward(resp.position.row(r).transpose(), l).tip_mm.transpose();
      cmd.row(r - r0) = kin_->forward(sp_->position.row(std::min(k, ns_ - 1)).transpose(), l).tip_mm.transpose();
    }
    add_rows(k0, resp, r0, r1, act.topRows(r1 - r0), cmd.topRows(r1 - r0));
  }
  next_ = k0 + m;
}

void SignalBinner::add(Eigen::Index k0, const drives::AxisResponse& resp,
                       const Eigen::Ref<const Eigen::MatrixXd>& actual_tip_mm,
                       const Eigen::Ref<const Eigen::MatrixXd>& command_tip_mm) {
  const Eigen::Index m = resp.samples();
  check_block(k0, m);
  if (actual_tip_mm.rows() != m || actual_tip_mm.cols() != 3 || command_tip_mm.rows() != m ||
      command_tip_mm.cols() != 3)
    throw core::Error(fmt::format("signals: {} x {} actual and {} x {} commanded tips for a block of {} rows",
                                  actual_tip_mm.rows(), actual_tip_mm.cols(), command_tip_mm.rows(),
                                  command_tip_mm.cols(), m));
  add_rows(k0, resp, 0, m, actual_tip_mm, command_tip_mm);
  next_ = k0 + m;
}

// Rows [r0, r1) of a block starting at row k0; the tips are those rows' (row 0: row r0).
void SignalBinner::add_rows(Eigen::Index k0, const drives::AxisResponse& resp, Eigen::Index r0, Eigen::Index r1,
                            const Eigen::Ref<const Eigen::MatrixXd>& act,
                            const Eigen::Ref<const Eigen::MatrixXd>& cmd) {
  const core::Setpoints& sp = *sp_;
  const double te = te_;
  const Eigen::Index m = r1 - r0;
  ts_.resize(static_cast<std::size_t>(m));
  for (Eigen::Index i = 0; i < m; ++i) ts_[static_cast<std::size_t>(i)] = static_cast<double>(k0 + r0 + i) * te;
  fold_column<false>(0, k0, r0, r1, ts_.data());
  for (const AxisColumns& ac : axes_) {
    const Eigen::Index ai = ac.axis;
    const double f = ac.scale;
    // Setpoints as the drives receive them: held at the last one while the axes settle, at rest before the first.
    auto x = [&](Eigen::Index k) { return sp.position(std::clamp<Eigen::Index>(k, 0, ns_ - 1), ai); };
    const int c = ac.first;
    const auto pos = resp.position.col(ai), vel = resp.velocity.col(ai), acc = resp.acceleration.col(ai),
               jerk = resp.jerk.col(ai), cur = resp.current_mean_A.col(ai), peak = resp.current_peak_A.col(ai);
    // The setpoint, its differences and the tracking error, computed for all the rows first (the setpoints k-3..k
    // of the rows in one array, so that the loop of divisions runs without a clamp per value and vectorises; each
    // value by the same expression as per row before), then folded; then the drive's own signals.
    xs_.resize(static_cast<std::size_t>(m + 3));
    for (Eigen::Index i = 0; i < m + 3; ++i) xs_[static_cast<std::size_t>(i)] = x(k0 + r0 - 3 + i);
    for (auto& col : sv_) col.resize(static_cast<std::size_t>(m));
    {
      const double* __restrict xv = xs_.data();
      const double* __restrict pv = pos.data() + r0;
      double* __restrict v0 = sv_[0].data();
      double* __restrict v1 = sv_[1].data();
      double* __restrict v2 = sv_[2].data();
      double* __restrict v3 = sv_[3].data();
      double* __restrict v4 = sv_[4].data();
      Eigen::Index i = 0;
#if defined(__SSE2__)
      // Two rows at a time (GCC leaves this loop scalar): the same operations on each lane, so the same bits.
      {
        const __m128d vf = _mm_set1_pd(f), vte = _mm_set1_pd(te), vte2 = _mm_set1_pd(te * te),
                      vte3 = _mm_set1_pd(te * te * te), two = _mm_set1_pd(2.0), three = _mm_set1_pd(3.0);
        for (; i + 2 <= m; i += 2) {
          const __m128d xk = _mm_loadu_pd(xv + i + 3), x1 = _mm_loadu_pd(xv + i + 2), x2 = _mm_loadu_pd(xv + i + 1),
                        x3 = _mm_loadu_pd(xv + i);
          _mm_storeu_pd(v0 + i, _mm_mul_pd(xk, vf));
          _mm_storeu_pd(v1 + i, _mm_mul_pd(_mm_sub_pd(xk, _mm_loadu_pd(pv + i)), vf));
          _mm_storeu_pd(v2 + i, _mm_mul_pd(_mm_div_pd(_mm_sub_pd(xk, x1), vte), vf));
          _mm_storeu_pd(v3 + i, _mm_mul_pd(_mm_div_pd(_mm_add_pd(_mm_sub_pd(xk, _mm_mul_pd(two, x1)), x2), vte2), vf));
          const __m128d d3 = _mm_sub_pd(_mm_add_pd(_mm_sub_pd(xk, _mm_mul_pd(three, x1)), _mm_mul_pd(three, x2)), x3);
          _mm_storeu_pd(v4 + i, _mm_mul_pd(_mm_div_pd(d3, vte3), vf));
        }
      }
#endif
      for (; i < m; ++i) {
        const double xk = xv[i + 3], x1 = xv[i + 2], x2 = xv[i + 1], x3 = xv[i];
        v0[i] = xk * f;
        v1[i] = (xk - pv[i]) * f;
        v2[i] = (xk - x1) / te * f;
        v3[i] = (xk - 2 * x1 + x2) / (te * te) * f;
        v4[i] = (xk - 3 * x1 + 3 * x2 - x3) / (te * te * te) * f;
      }
    }
    for (int i = 0; i < 5; ++i) fold_column<false>(c + kSetpointColumn[i], k0, r0, r1, sv_[i].data());
    // The drive's own signals, in axis units (x * 1 is x, bit for bit: linear axes skip the product).
    const double* drive[6] = {pos.data(), vel.data(), acc.data(), jerk.data(), cur.data(), peak.data()};
    for (int i = 0; i < 6; ++i) {
      const double* d = drive[i] + r0;
      if (i < 4 && f != 1.0)
        fold_column<true>(c + kDriveColumn[i], k0, r0, r1, d, f);
      else
        fold_column<false>(c + kDriveColumn[i], k0, r0, r1, d);
    }
  }
  const auto rows = static_cast<std::size_t>(r1 - r0);
  for (auto* v : {&feed_, &speed_, &speed_actual_, &path_, &cutting_}) v->resize(rows);
  for (Eigen::Index r = r0; r < r1; ++r) {
    const Eigen::Index k = k0 + r;
    const auto i = static_cast<std::size_t>(r - r0);
    const bool cut = cutting(k);
    double feed = kNaN;
    if (k < ns_ && cut) {
      const core::Move& mv = program_->moves[static_cast<std::size_t>(move_of(k))];
      feed = mv.feed_mode == core::FeedMode::UnitsPerMinute ? mv.feed_mm_per_min * feed_scale_ : kNaN;
    }
    feed_[i] = feed;
    speed_[i] = k < ns_ ? sp.path_speed_mm_per_s[k] * 60 : 0.0;
    const Eigen::Vector3d p = act.row(r - r0).transpose();
    speed_actual_[i] = k == 0 ? 0.0 : (p - prev_actual_).norm() / te * 60;
    prev_actual_ = p;
    const Eigen::Vector3d q = cmd.row(r - r0).transpose();
    if (k > 0 && cut) cutting_path_ += (q - prev_command_).norm();
    prev_command_ = q;
    path_[i] = cutting_path_;
    cutting_[i] = cut ? 1.0 : 0.0;
  }
  fold_column<false>(c_feed_, k0, r0, r1, feed_.data());
  fold_column<false>(c_speed_, k0, r0, r1, speed_.data());
  fold_column<false>(c_speed_actual_, k0, r0, r1, speed_actual_.data());
  fold_column<false>(c_path_, k0, r0, r1, path_.data());
  fold_column<false>(c_cutting_, k0, r0, r1, cutting_.data());
}

void SignalBinner::add_contour(const motion::ContourError& ce) {
  if (ce.signed_mm.size() != n_)
    throw core::Error(fmt::format("signals: {} contour-error samples for {} drive samples", ce.signed_mm.size(), n_));
  // A chunk of rows at a time (rapids' rows NaN: their bins fold in row order, the others packed).
  constexpr Eigen::Index kChunk = 65536;
  for (Eigen::Index r0 = 0; r0 < n_; r0 += kChunk) {
    const Eigen::Index r1 = std::min(n_, r0 + kChunk);
    ts_.resize(static_cast<std::size_t>(r1 - r0));
    for (Eigen::Index k = r0; k < r1; ++k) ts_[static_cast<std::size_t>(k - r0)] = cutting(k) ? ce.signed_mm[k] : kNaN;
    fold_column<false>(c_contour_, 0, r0, r1, ts_.data());
  }
}

BinnedSignals SignalBinner::finish() {
  if (next_ != n_) throw core::Error(fmt::format("signals: {} of {} rows binned", next_, n_));
  BinnedSignals out = std::move(out_);
  out.samples = n_;
  out.bin_samples = bs_;
  out.min.resize(bins_, static_cast<Eigen::Index>(columns_.size()));
  out.max.resize(bins_, static_cast<Eigen::Index>(columns_.size()));
  for (std::size_t c = 0; c < columns_.size(); ++c) {
    out.min.col(static_cast<Eigen::Index>(c)) = columns_[c].lo;
    out.max.col(static_cast<Eigen::Index>(c)) = columns_[c].hi;
  }
  return out;
}

BinnedSignals motion_signals(const core::Job& job, const core::ToolPath& program, const core::Setpoints& sp,
                             const drives::AxisResponse& resp, const motion::ContourError& ce, double feed_scale,
                             Eigen::Index max_bins) {
  const Eigen::Index n = resp.samples();
  if (n == 0 || sp.samples() == 0) throw core::Error("signals: the run has no samples");
  if (ce.signed_mm.size() != n)
    throw core::Error(fmt::format("signals: {} contour-error samples for {} drive samples", ce.signed_mm.size(), n));
  SignalBinner bins(job, program, sp, n, feed_scale, max_bins);
  bins.add(0, resp);
  bins.add_contour(ce);
  return bins.finish();
}

void write_signals(const std::filesystem::path& file, const BinnedSignals& s) {
  core::CsvWriter out(file);
  out.comment(
      "vmsim signals 1: per-bin minimum and maximum of each signal (columns NAME.min, NAME.max) over bins of "
      "bin_samples consecutive samples, so that peaks survive the decimation; nan: undefined over the whole bin");
  out.comment("job=" + s.job);
  out.comment(fmt::format("period_s={:.9g}", s.period_s));
  out.comment(fmt::format("samples={}", s.samples));
  out.comment(fmt::format("bin_samples={}", s.bin_samples));
  std::string axes, held;
  for (const auto& [name, unit] : s.axes) axes += (axes.empty() ? "" : ",") + name + ":" + unit;
  for (const auto& name : s.held_axes) held += (held.empty() ? "" : ",") + name;
  out.comment("axes=" + axes);
  out.comment("held_axes=" + held);
  for (const auto& [name, v] : s.limits) out.comment("limit " + name + '=' + fmt::format("{:.9g}", v));
  std::vector<std::string> header;
  for (const std::string& n : s.names) {
    header.push_back(n + ".min");
    header.push_back(n + ".max");
  }
  out.header(header);
  std::string line;
  for (Eigen::Index b = 0; b < s.bins(); ++b) {
    line.clear();
    for (Eigen::Index c = 0; c < static_cast<Eigen::Index>(s.names.size()); ++c) {
      if (c) line += ',';
      append_cell(line, s.min(b, c));
      line += ',';
      append_cell(line, s.max(b, c));
    }
    out.row(line);
  }
  out.commit();
}

BinnedSignals read_signals(const std::filesystem::path& file) {
  core::CsvReader in(file);
  const std::string& fname = in.name();
  BinnedSignals s;
  bool magic = false;
  // The metadata: the '#' lines before the header.
  for (const core::CsvComment& c : in.comments()) {
    if (c.text.rfind("# vmsim signals 1", 0) == 0) magic = true;
    const auto kv = core::comment_key_value(c.text);
    if (!kv) continue;
    const std::string key(kv->first), value(kv->second);
    auto number_of = [&](const char* what) {
      const auto v = core::parse_number(value);
      if (!v)
        throw core::Error(
            core::located(fname, c.line, std::string("expected a number for ") + what + ", found \"" + value + "\""));
      return *v;
    };
    if (key == "job")
      s.job = value;
    else if (key == "period_s")
      s.period_s = number_of("period_s");
    else if (key == "samples")
      s.samples = static_cast<Eigen::Index>(number_of("samples"));
    else if (key == "bin_samples")
      s.bin_samples = static_cast<Eigen::Index>(number_of("bin_samples"));
    else if (key == "axes") {
      std::stringstream ss(value);
      std::string item;
      while (std::getline(ss, item, ',')) {
        const auto colon = item.find(':');
        if (colon == std::string::npos) throw core::Error(core::located(fname, c.line, "expected axes=NAME:UNIT,..."));
        s.axes.emplace_back(item.substr(0, colon), item.substr(colon + 1));
      }
    } else if (key == "held_axes") {
      std::stringstream ss(value);
      std::string item;
      while (std::getline(ss, item, ','))
        if (!item.empty()) s.held_axes.push_back(item);
    } else if (key.rfind("limit ", 0) == 0) {
      s.limits[key.substr(6)] = number_of(key.c_str());
    }
  }
  if (!magic) {
    const int at = in.has_header() ? in.header_line() : 0;
    throw core::Error(core::located(fname, at, "not a vmsim signals file (no \"# vmsim signals 1\" line)"));
  }
  if (!in.has_header()) throw core::Error(fname + ": no column header");
  const std::vector<std::string>& cells = in.columns();
  if (cells.size() % 2 != 0) throw in.error("expected pairs of NAME.min,NAME.max columns", in.header_line());
  for (std::size_t c = 0; c < cells.size(); c += 2) {
    const std::string& a = cells[c];
    const std::string& b = cells[c + 1];
    if (a.size() < 5 || a.substr(a.size() - 4) != ".min" || b != a.substr(0, a.size() - 4) + ".max")
      throw in.error("expected NAME.min,NAME.max, found \"" + a + "," + b + "\"", in.header_line());
    s.names.push_back(a.substr(0, a.size() - 4));
  }
  if (s.find("t_s") < 0) throw core::Error(fname + ": no t_s column");
  if (!(s.period_s > 0)) throw core::Error(fname + ": period_s must be > 0");
  const std::size_t columns = cells.size();
  std::vector<double> values;
  while (in.next())
    for (std::size_t c = 0; c < columns; ++c) values.push_back(in.number_or_nan(c));
  const auto nb = static_cast<Eigen::Index>(values.size() / std::max<std::size_t>(1, columns));
  const auto nc = static_cast<Eigen::Index>(s.names.size());
  s.min.resize(nb, nc);
  s.max.resize(nb, nc);
  for (Eigen::Index b = 0; b < nb; ++b)
    for (Eigen::Index c = 0; c < nc; ++c) {
      s.min(b, c) = values[static_cast<std::size_t>(b) * columns + static_cast<std::size_t>(2 * c)];
      s.max(b, c) = values[static_cast<std::size_t>(b) * columns + static_cast<std::size_t>(2 * c + 1)];
    }
  return s;
}

}  // namespace vmsim::sim
