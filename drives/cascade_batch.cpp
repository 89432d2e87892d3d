#include "drives/cascade_batch.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <immintrin.h>

#include <algorithm>
#include <bit>
#include <cmath>

// Every expression below repeats CascadeAxis' (cascade_axis.cpp) operation for operation and in the same order, so
// that the batch gives its bits; tests/drives/cascade_batch_test.cpp holds the two together. A change to the
// cascade's physics is made in both places.
namespace vmsim::drives {

// Four lanes per vector (GCC's vector extensions: two SSE2 operations each on the generic build, one AVX2 operation
// where the processor has it). Element-wise IEEE arithmetic gives each lane the bits of the scalar code; the branches
// of the scalar code become selects, the scalar libm calls (gravity's sin, Stribeck's exp) stay scalar calls.
// The vectors live only inside always-inlined functions: no call passes one, so -Wpsabi's ABI note does not apply.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
using CbV = double __attribute__((vector_size(32)));
using CbM = decltype(CbV{} < CbV{});  // lane masks: all bits set or none

// The active lanes of a period, four to a vector: constants and state in slots (structure of arrays).
struct alignas(32) CascadePack {
  static constexpr int kSlots = CascadeBatch::kMaxLanes;
  alignas(32) double kpv[kSlots], kiv[kSlots], ilim[kSlots], kpc[kSlots], kic[kSlots], ulim[kSlots];
  alignas(32) double p00[kSlots], p01[kSlots], p10[kSlots], p11[kSlots], p20[kSlots], p21[kSlots];
  alignas(32) double gu0[kSlots], gu1[kSlots], gu2[kSlots], gt0[kSlots], gt1[kSlots], gt2[kSlots];
  alignas(32) double sa[kSlots], sb[kSlots], kt[kSlots], brk[kSlots], win[kSlots], coul[kSlots], gconst[kSlots];
  alignas(32) double r[kSlots];
  alignas(32) long long fr[kSlots];  // friction: all bits set
  // Scalar parts: a tilting gravity's sin, a Stribeck curve's exp.
  bool tilt[kSlots], strib[kSlots];
  double g_nm[kSlots], g_off[kSlots], s_static[kSlots], s_vel[kSlots];
  // State.
  alignas(32) double i[kSlots], w[kSlots], x[kSlots], ic[kSlots], iv[kSlots], iset[kSlots], u[kSlots];
  alignas(32) double w_cmd[kSlots], i_ff[kSlots], i_sum[kSlots], i_peak[kSlots];
  // run_rows: each lane's Te and, after a period, its sample's derived values and whether it left the state as it was.
  alignas(32) double te[kSlots];
  alignas(32) double o_vel[kSlots], o_acc[kSlots], o_mean[kSlots];
  alignas(32) long long o_fixed[kSlots];
  // run_rows: the NC's commands of up to kChunk rows, computed before those rows are stepped. Per lane (not slot):
  // the delayed position command, the gain Kv, the product KF v_d and the current feedforward of each row.
  static constexpr int kChunk = 64;
  alignas(32) double c_pos[kChunk], c_vel[kChunk], c_acc[kChunk];
  alignas(32) double c_xd[kSlots][kChunk], c_kv[kSlots][kChunk], c_kfvd[kSlots][kChunk], c_ff[kSlots][kChunk];
};

namespace {

bool cb_same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// CascadeAxis::gravity_torque at position x.
inline double cb_gravity(const CascadeLane& L, double x) {
  switch (L.gravity) {
    case 0:
      return 0.0;
    case 1:
      return L.gravity_Nm;
    default:
      return L.gravity_Nm * std::sin(x - L.gravity_offset);
  }
}

// CascadeAxis::friction_level.
inline double cb_friction_level(const CascadeLane& L, double abs_w) {
  if (L.stribeck_static <= 0.0) return L.coulomb;
  const double q = abs_w / L.stribeck_velocity;
  return L.coulomb + (L.stribeck_static - L.coulomb) * std::exp(-q * q);
}

[[gnu::always_inline]] inline CbV cb_load(const double* p) {
  CbV v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
[[gnu::always_inline]] inline void cb_store(double* p, CbV v) { __builtin_memcpy(p, &v, sizeof v); }

// The constants of lanes active[0 .. m) into the pack's slots 0 .. m, and of lane active[0] into the slots that
// fill the last vector (computed, never read).
void cb_pack_constants(CascadePack& P, const CascadeLane* lanes, const int* active, int m) {
  const int slots = (m + 3) / 4 * 4;
  for (int j = 0; j < slots; ++j) {
    const CascadeLane& L = lanes[active[j < m ? j : 0]];
    P.kpv[j] = L.kpv, P.kiv[j] = L.kiv, P.ilim[j] = L.current_limit;
    P.kpc[j] = L.kpc, P.kic[j] = L.kic, P.ulim[j] = L.voltage_limit;
    P.p00[j] = L.phi[0][0], P.p01[j] = L.phi[0][1], P.p10[j] = L.phi[1][0];
    P.p11[j] = L.phi[1][1], P.p20[j] = L.phi[2][0], P.p21[j] = L.phi[2][1];
    P.gu0[j] = L.gam_u[0], P.gu1[j] = L.gam_u[1], P.gu2[j] = L.gam_u[2];
    P.gt0[j] = L.gam_t[0], P.gt1[j] = L.gam_t[1], P.gt2[j] = L.gam_t[2];
    P.sa[j] = L.stuck_a, P.sb[j] = L.stuck_b, P.kt[j] = L.kt, P.brk[j] = L.breakaway, P.win[j] = L.stick_window;
    P.coul[j] = L.coulomb;
    P.gconst[j] = L.gravity == 1 ? L.gravity_Nm : 0.0;
    P.r[j] = L.r;
    P.te[j] = L.te;
    P.fr[j] = L.friction ? -1LL : 0LL;
    P.tilt[j] = j < m && L.gravity == 2;
    P.strib[j] = j < m && L.stribeck_static > 0.0;
    P.g_nm[j] = L.gravity_Nm, P.g_off[j] = L.gravity_offset;
    P.s_static[j] = L.stribeck_static, P.s_vel[j] = L.stribeck_velocity;
  }
}

// The state of lanes active[0 .. m) into the slots (the filling slots: lane active[0]'s), and back.
void cb_load_state(CascadePack& P, const CascadeLane* lanes, const int* active, int m) {
  const int slots = (m + 3) / 4 * 4;
  for (int j = 0; j < slots; ++j) {
    const CascadeLane& L = lanes[active[j < m ? j : 0]];
    P.i[j] = L.i, P.w[j] = L.w, P.x[j] = L.x, P.ic[j] = L.ic, P.iv[j] = L.iv, P.iset[j] = L.iset, P.u[j] = L.u;
  }
}
void cb_flush_state(const CascadePack& P, CascadeLane* lanes, const int* active, int m) {
  for (int j = 0; j < m; ++j) {
    CascadeLane& L = lanes[active[j]];
    L.i = P.i[j], L.w = P.w[j], L.x = P.x[j], L.ic = P.ic[j], L.iv = P.iv[j], L.iset = P.iset[j], L.u = P.u[j];
  }
}

// A lane's position loop as CascadeAxis::advance runs it: the axis' own delay lines (by address) and gains.
struct CbNcLane {
  double *pos_line, *vel_line, *acc_line;
  int *pos_head, *ff_head;
  int pos_n, ff_n;
  double kv, kf;
};

// What run_rows hands to its loop (CascadeBatch's members, the axes' delay lines).
struct CbRows {
  CascadePack* P;
  CascadeLane* lanes;
  CascadeRowLane* rl;
  CbNcLane* nc;
  int n_lanes, per_te, per_vel;
  int* packed;  // the lanes whose constants are in the slots
  int* packed_m;
  long long* skipped;
};

// The kernel (drives/cascade_batch_kernel.inc): generic, and for AVX2, where a whole-vector test is one vmovmskpd
// (GCC inlines the intrinsic only into code compiled for AVX, hence the copy under the pragma); AVX-512VL below.
namespace cb_generic {
[[gnu::always_inline]] inline bool cb_any(CbM m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }
#include "drives/cascade_batch_kernel.inc"
}  // namespace cb_generic
#pragma GCC push_options
#pragma GCC target("avx2")
namespace cb_avx2 {
[[gnu::always_inline]] inline bool cb_any(CbM m) { return _mm256_movemask_pd(reinterpret_cast<__m256d>(m)) != 0; }
#include "drives/cascade_batch_kernel.inc"
}  // namespace cb_avx2
#pragma GCC pop_options
// The same text for AVX-512VL processors, still on 256-bit vectors: the EVEX encoding's 32 vector registers hold the
// current loop's state and temporaries (with AVX2's 16 the compiler spills some and store-to-load forwarding lands
// on the period's dependency chain). Same operations: AVX-512F brings FMA, and GCC contracts a * b + c into one by
// default (-ffp-contract=fast), which rounds once where the scalar code rounds twice: contraction is turned off here.
#pragma GCC push_options
#pragma GCC target("avx2,avx512f,avx512vl")
#pragma GCC optimize("fp-contract=off")
namespace cb_avx512 {
[[gnu::always_inline]] inline bool cb_any(CbM m) { return _mm256_movemask_pd(reinterpret_cast<__m256d>(m)) != 0; }
#include "drives/cascade_batch_kernel.inc"
}  // namespace cb_avx512
#pragma GCC pop_options

// The kernel to run: the widest the processor supports within the tests' limit.
CascadeBatchKernel cb_kernel() {
  const CascadeBatchKernel limit = cascade_batch_kernel_limit();
  for (CascadeBatchKernel k : {CascadeBatchKernel::Avx512, CascadeBatchKernel::Avx2})
    if (k <= limit && cascade_batch_supports(k)) return k;
  return CascadeBatchKernel::Generic;
}

}  // namespace

bool cascade_batch_supports(CascadeBatchKernel kernel) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  static const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  switch (kernel) {
    case CascadeBatchKernel::Generic:
      return true;
    case CascadeBatchKernel::Avx2:
      return avx2;
    case CascadeBatchKernel::Avx512:
      return avx512;
  }
  return false;
}

CascadeBatchKernel& cascade_batch_kernel_limit() {
  static CascadeBatchKernel limit = CascadeBatchKernel::Avx512;
  return limit;
}

bool CascadeBatch::compatible(const CascadeAxis& a, const CascadeAxis& b) {
  return a.current_per_te_ == b.current_per_te_ && a.current_per_velocity_ == b.current_per_velocity_;
}

CascadeBatch::CascadeBatch(const std::vector<CascadeAxis*>& axes, bool trace) : axes_(axes), trace_(trace) {
  if (axes.empty() || static_cast<int>(axes.size()) > kMaxLanes)
    throw core::Error(fmt::format("a batch of cascade drives holds 1 to {} axes, given {}", kMaxLanes, axes.size()));
  for (const CascadeAxis* a : axes)
    if (!compatible(*a, *axes.front()))
      throw core::Error("a batch of cascade drives needs the same loop periods on every axis");
  per_te_ = axes.front()->current_per_te_;
  per_velocity_ = axes.front()->current_per_velocity_;
  lanes_.resize(axes.size());
  for (std::size_t l = 0; l < axes.size(); ++l) {
    const CascadeAxis& a = *axes[l];
    const core::DriveParams& p = a.params_;
    CascadeLane& L = lanes_[l];
    L = CascadeLane{};
    L.kpv = a.kpv_, L.kiv = a.kiv_, L.kpc = a.kpc_, L.kic = a.kic_;
    L.current_limit = p.current_limit_A, L.voltage_limit = p.voltage_limit_V;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) L.phi[r][c] = a.phi_[r][c];
      L.gam_u[r] = a.gam_u_[r];
      L.gam_t[r] = a.gam_t_[r];
    }
    L.stuck_a = a.stuck_a_, L.stuck_b = a.stuck_b_;
    L.kt = p.torque_constant_Nm_per_A, L.breakaway = a.breakaway_Nm_, L.stick_window = a.stick_window_;
    L.coulomb = p.coulomb_Nm, L.stribeck_static = p.stribeck_static_Nm;
    L.stribeck_velocity = p.stribeck_velocity_rad_per_s;
    L.gravity_Nm = p.gravity_Nm, L.gravity_offset = p.gravity_angle_offset_rad;
    L.gravity = p.gravity == core::DriveParams::Gravity::None       ? 0
                : p.gravity == core::DriveParams::Gravity::Constant ? 1
                                                                    : 2;
    L.friction = a.friction_;
    L.r = a.r_, L.inv_r = a.inv_r_, L.ff_current_per_accel = a.ff_current_per_accel_, L.te = a.te_;
    L.i = a.i_, L.w = a.w_, L.x = a.x_, L.ic = a.ic_, L.iv = a.iv_, L.iset = a.iset_, L.u = a.u_;
    L.fixed = false;
  }
  pack_ = std::make_unique<CascadePack>();
  if (trace_) {
    trace_buf_.resize(axes.size() * static_cast<std::size_t>(per_te_));
    trace_slots_.resize(static_cast<std::size_t>(kMaxLanes) * static_cast<std::size_t>(per_te_));
  }
}

CascadeBatch::~CascadeBatch() = default;
CascadeBatch::CascadeBatch(CascadeBatch&&) noexcept = default;

// The constants of lanes active[0 .. m) into the pack's slots 0 .. m, and of lane active[0] into the slots that
// fill the last vector (computed, never read). Only when the active lanes change.
void CascadeBatch::pack(const int* active, int m) {
  if (m == packed_m_ && std::equal(active, active + m, packed_)) return;
  cb_pack_constants(*pack_, lanes_.data(), active, m);
  std::copy(active, active + m, packed_);
  packed_m_ = m;
}

void CascadeBatch::run_rows(CascadeRowLane* rl, long long k0, long long k1, long long base, long long n_set,
                            long long rows, double te) {
  CbNcLane nc[kMaxLanes];
  for (int l = 0; l < lanes(); ++l) {
    CascadeAxis& a = *axes_[static_cast<std::size_t>(l)];
    nc[l] = CbNcLane{a.pos_line_.data(),
                     a.vel_line_.data(),
                     a.acc_line_.data(),
                     &a.pos_head_,
                     &a.ff_head_,
                     static_cast<int>(a.pos_line_.size()),
                     static_cast<int>(a.vel_line_.size()),
                     a.params_.kv_per_s,
                     a.params_.kf};
  }
  CbRows c{pack_.get(), lanes_.data(), rl, nc, lanes(), per_te_, per_velocity_, packed_, &packed_m_, &skipped_};
  switch (cb_kernel()) {
    case CascadeBatchKernel::Avx512:
      cb_avx512::cb_rows(c, k0, k1, base, n_set, rows, te);
      break;
    case CascadeBatchKernel::Avx2:
      cb_avx2::cb_rows(c, k0, k1, base, n_set, rows, te);
      break;
    case CascadeBatchKernel::Generic:
      cb_generic::cb_rows(c, k0, k1, base, n_set, rows, te);
      break;
  }
}

const InnerSample* CascadeBatch::trace(int lane) const {
  return trace_ ? trace_buf_.data() + static_cast<std::size_t>(lane) * static_cast<std::size_t>(per_te_) : nullptr;
}

void CascadeBatch::store() const {
  for (std::size_t l = 0; l < axes_.size(); ++l) {
    CascadeAxis& a = *axes_[l];
    const CascadeLane& L = lanes_[l];
    a.i_ = L.i, a.w_ = L.w, a.x_ = L.x, a.ic_ = L.ic, a.iv_ = L.iv, a.iset_ = L.iset, a.u_ = L.u;
  }
}

void CascadeBatch::step(const AxisCommand* commands, AxisSample* samples) {
  if (trace_)
    advance<true>(commands, samples);
  else
    advance<false>(commands, samples);
}

template <bool kTrace>
void CascadeBatch::advance(const AxisCommand* commands, AxisSample* samples) {
  // The position loop of every lane (CascadeAxis::advance up to the inner loops), and which lanes must run.
  int active[kMaxLanes];
  int m = 0;
  for (int l = 0; l < lanes(); ++l) {
    CascadeAxis& a = *axes_[static_cast<std::size_t>(l)];
    CascadeLane& L = lanes_[static_cast<std::size_t>(l)];
    const AxisCommand& c = commands[l];
    const double kv = std::isnan(c.kv_per_s) ? a.params_.kv_per_s : c.kv_per_s;
    const double kf = std::isnan(c.kf) ? a.params_.kf : c.kf;
    const int pos_n = static_cast<int>(a.pos_line_.size()), ff_n = static_cast<int>(a.vel_line_.size());
    a.pos_line_[static_cast<std::size_t>(a.pos_head_)] = c.position;
    a.pos_head_ = a.pos_head_ + 1 == pos_n ? 0 : a.pos_head_ + 1;
    const double xd = a.pos_line_[static_cast<std::size_t>(a.pos_head_)];
    a.vel_line_[static_cast<std::size_t>(a.ff_head_)] = c.velocity;
    a.acc_line_[static_cast<std::size_t>(a.ff_head_)] = c.acceleration;
    a.ff_head_ = a.ff_head_ + 1 == ff_n ? 0 : a.ff_head_ + 1;
    const double vd = a.vel_line_[static_cast<std::size_t>(a.ff_head_)];
    const double ad = a.acc_line_[static_cast<std::size_t>(a.ff_head_)];
    L.w_cmd = (kv * (xd - L.x) + kf * vd) * L.inv_r;
    L.i_ff = L.ff_current_per_accel * ad;
    // At a fixed point with the same inputs: this period is the last one again (its trace is still in trace_buf_).
    if (L.fixed && cb_same_bits(L.w_cmd, L.last_w_cmd) && cb_same_bits(L.i_ff, L.last_i_ff)) {
      samples[l] = L.last;
      ++skipped_;
      continue;
    }
    L.last_w_cmd = L.w_cmd, L.last_i_ff = L.i_ff;
    L.w_start = L.w;
    L.i_sum = 0.0, L.i_peak = 0.0;
    active[m++] = l;
  }
  if (m == 0) return;

  // Before the period, to tell whether it changes the state.
  double before[kMaxLanes][7];
  for (int j = 0; j < m; ++j) {
    const CascadeLane& L = lanes_[static_cast<std::size_t>(active[j])];
    const double s[7] = {L.i, L.w, L.x, L.ic, L.iv, L.iset, L.u};
    std::copy(s, s + 7, before[j]);
  }

  // The inner loops of the active lanes, four to a vector.
  pack(active, m);
  CascadePack& P = *pack_;
  CascadeLane* lanes = lanes_.data();
  const int slots = (m + 3) / 4 * 4;
  for (int j = 0; j < slots; ++j) {
    const CascadeLane& L = lanes[active[j < m ? j : 0]];
    P.i[j] = L.i, P.w[j] = L.w, P.x[j] = L.x, P.ic[j] = L.ic, P.iv[j] = L.iv, P.iset[j] = L.iset, P.u[j] = L.u;
    P.w_cmd[j] = L.w_cmd, P.i_ff[j] = L.i_ff;
  }
  InnerSample* trace = kTrace ? trace_slots_.data() : nullptr;
  switch (cb_kernel()) {
    case CascadeBatchKernel::Avx512:
      cb_avx512::cb_periods<kTrace>(P, m, per_te_, per_velocity_, trace);
      break;
    case CascadeBatchKernel::Avx2:
      cb_avx2::cb_periods<kTrace>(P, m, per_te_, per_velocity_, trace);
      break;
    case CascadeBatchKernel::Generic:
      cb_generic::cb_periods<kTrace>(P, m, per_te_, per_velocity_, trace);
      break;
  }
  const int n = per_te_;
  for (int j = 0; j < m; ++j) {
    CascadeLane& L = lanes[active[j]];
    L.i = P.i[j], L.w = P.w[j], L.x = P.x[j], L.ic = P.ic[j], L.iv = P.iv[j], L.iset = P.iset[j], L.u = P.u[j];
    L.i_sum = P.i_sum[j], L.i_peak = P.i_peak[j];
    if constexpr (kTrace)
      std::copy_n(trace_slots_.begin() + static_cast<std::ptrdiff_t>(j) * per_te_, per_te_,
                  trace_buf_.begin() + static_cast<std::ptrdiff_t>(active[j]) * per_te_);
  }

  for (int j = 0; j < m; ++j) {
    const int l = active[j];
    CascadeLane& L = lanes[l];
    // CascadeAxis::sample() and the end of advance().
    AxisSample s;
    s.position = L.x;
    s.velocity = L.r * L.w;
    s.current_A = L.i;
    s.current_setpoint_A = L.iset;
    s.current_mean_A = L.i_sum / n;
    s.current_peak_A = L.i_peak;
    s.acceleration = L.r * (L.w - L.w_start) / L.te;
    samples[l] = s;
    L.last = s;
    const double after[7] = {L.i, L.w, L.x, L.ic, L.iv, L.iset, L.u};
    L.fixed = true;
    for (int q = 0; q < 7; ++q) L.fixed = L.fixed && cb_same_bits(after[q], before[j][q]);
  }
}

}  // namespace vmsim::drives

#pragma GCC diagnostic pop
