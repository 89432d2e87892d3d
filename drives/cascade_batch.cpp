#include "drives/cascade_batch.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

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

// Whether any lane's mask is set.
[[gnu::always_inline]] inline bool cb_any(CbM m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }

// A PI with its output saturated at +-lim and the integrator stopped while saturated and pushed further out
// (CascadeAxis::velocity_loop, with the current feedforward ff added, and current_loop, without), lane by lane.
template <bool kFeedforward>
[[gnu::always_inline]] inline void cb_saturated_pi(CbV err, CbV kp, CbV ki, CbV ff, CbV lim, CbV& integ_state,
                                                   CbV& out_held) {
  const CbV integ = integ_state + ki * err;
  CbV out = kp * err + integ;
  if constexpr (kFeedforward) out = out + ff;
  const CbM hi = out > lim, lo = out < -lim;
  const CbM sat = hi | lo;
  if (!cb_any(sat)) {  // the common case: no lane saturates
    out_held = out;
    integ_state = integ;
  } else {
    out_held = hi ? lim : (lo ? -lim : out);
    const CbV zero = CbV{};
    const CbM keep = hi ? (err < zero) : (lo ? (err > zero) : (CbM{} == CbM{}));
    integ_state = keep ? integ : integ_state;
  }
}

// One period (per_te current periods) of the four lanes in slots [q0, q0 + 4): CascadeAxis::advance's inner loops,
// lane by lane the same operations. trace: slot-major, per_te samples a slot; `real` lanes of the four are traced.
template <bool kTrace, bool kOutputs>
[[gnu::always_inline]] inline void cb_period(CascadePack& P, int q0, int per_te, int per_vel, InnerSample* trace,
                                             int real) {
  const CbM abs_mask = CbM{} + 0x7fffffffffffffffLL;
  const CbV zero = CbV{}, one = zero + 1.0, minus_one = zero - 1.0;
  const CbV kpv = cb_load(P.kpv + q0), kiv = cb_load(P.kiv + q0), ilim = cb_load(P.ilim + q0);
  const CbV kpc = cb_load(P.kpc + q0), kic = cb_load(P.kic + q0), ulim = cb_load(P.ulim + q0);
  const CbV w_cmd = cb_load(P.w_cmd + q0), i_ff = cb_load(P.i_ff + q0);
  const CbV kt = cb_load(P.kt + q0), brk = cb_load(P.brk + q0), win = cb_load(P.win + q0);
  const CbV coul = cb_load(P.coul + q0), gconst = cb_load(P.gconst + q0);
  CbM fr;
  __builtin_memcpy(&fr, P.fr + q0, sizeof fr);
  bool any_tilt = false, any_strib = false;
  for (int j = 0; j < 4; ++j) any_tilt |= P.tilt[q0 + j], any_strib |= P.strib[q0 + j];
  CbV i = cb_load(P.i + q0), w = cb_load(P.w + q0), x = cb_load(P.x + q0), ic = cb_load(P.ic + q0);
  CbV iv = cb_load(P.iv + q0), iset = cb_load(P.iset + q0), u = cb_load(P.u + q0);
  CbV i_sum = zero, i_peak = zero;
  const CbV i0 = i, w0 = w, x0 = x, ic0 = ic, iv0 = iv, iset0 = iset, u0 = u;
  const auto gravity_at = [&](CbV at) {
    CbV g = gconst;
    if (any_tilt)
      for (int j = 0; j < 4; ++j)
        if (P.tilt[q0 + j]) g[j] = P.g_nm[q0 + j] * std::sin(at[j] - P.g_off[q0 + j]);
    return g;
  };
  // The friction while sliding at w (CascadeAxis::friction_level): Coulomb, with the Stribeck hump in the sliding
  // lanes that have one.
  const auto sliding_level = [&](CbM slides) {
    CbV level = coul;
    if (any_strib)
      for (int j = 0; j < 4; ++j)
        if (P.strib[q0 + j] && slides[j]) {
          const double q = std::abs(w[j]) / P.s_vel[q0 + j];
          level[j] = P.coul[q0 + j] + (P.s_static[q0 + j] - P.coul[q0 + j]) * std::exp(-q * q);
        }
    return level;
  };
  // The common case takes branches on whole-vector conditions (no lane saturates, every lane slides and none
  // reverses or nears a stop): the core predicts them, so the masks leave the loop-carried chains. Where a condition
  // fails, the selects below give every lane the scalar code's branch; both ways compute the same values.
  const auto any = [](CbM m) { return cb_any(m); };
  const bool all_friction = (fr[0] & fr[1] & fr[2] & fr[3]) != 0;
  int n = 0;
  for (int vs = 0; vs < per_te; vs += per_vel) {
    cb_saturated_pi<true>(w_cmd - w, kpv, kiv, i_ff, ilim, iv, iset);  // velocity PI (CascadeAxis::velocity_loop)
    for (int k = 0; k < per_vel; ++k, ++n) {
      cb_saturated_pi<false>(iset - i, kpc, kic, zero, ulim, ic, u);  // current PI (CascadeAxis::current_loop)
      if constexpr (kTrace) {
        const CbV rw = cb_load(P.r + q0) * w;
        for (int j = 0; j < real; ++j)
          trace[static_cast<std::size_t>(q0 + j) * static_cast<std::size_t>(per_te) + static_cast<std::size_t>(n)] =
              InnerSample{x[j], rw[j], i[j], iset[j], u[j]};
      }
      // Plant (CascadeAxis::plant): Karnopp friction as masks.
      CbV tau = -gravity_at(x);
      const CbM wz = w == zero;
      CbV dir;
      CbM stuck = CbM{};
      bool any_stuck = false;
      if (all_friction && !any(wz)) {  // every lane slides
        dir = w > zero ? one : minus_one;
        CbV level = coul;
        if (any_strib)
          for (int j = 0; j < 4; ++j)
            if (P.strib[q0 + j]) {
              const double q = std::abs(w[j]) / P.s_vel[q0 + j];
              level[j] = P.coul[q0 + j] + (P.s_static[q0 + j] - P.coul[q0 + j]) * std::exp(-q * q);
            }
        tau = tau - dir * level;
      } else {
        const CbV drive = kt * i + tau;
        stuck = fr & wz & ((CbV)((CbM)drive & abs_mask) <= brk);
        any_stuck = any(stuck);
        const CbM breaks = fr & wz & ~stuck;
        const CbM slides = fr & ~wz;
        if (all_friction && !any(breaks)) {
          // Every lane slides or stays stuck: the sliding lanes' torque as above; a stuck lane's linear step is
          // computed and then dropped (it keeps w and x, its current follows the winding alone).
          dir = w > zero ? one : minus_one;
          const CbV level = sliding_level(slides);
          tau = tau - dir * level;
        } else {
          dir = breaks ? (drive > zero ? one : minus_one) : (slides ? (w > zero ? one : minus_one) : zero);
          const CbV level = sliding_level(slides);
          tau = (breaks | slides) ? tau - dir * (breaks ? brk : level) : tau;
        }
      }
      const CbV p00 = cb_load(P.p00 + q0), p01 = cb_load(P.p01 + q0), gu0 = cb_load(P.gu0 + q0);
      const CbV gt0 = cb_load(P.gt0 + q0), p10 = cb_load(P.p10 + q0), p11 = cb_load(P.p11 + q0);
      const CbV gu1 = cb_load(P.gu1 + q0), gt1 = cb_load(P.gt1 + q0), p20 = cb_load(P.p20 + q0);
      const CbV p21 = cb_load(P.p21 + q0), gu2 = cb_load(P.gu2 + q0), gt2 = cb_load(P.gt2 + q0);
      const CbV i1 = p00 * i + p01 * w + gu0 * u + gt0 * tau;
      CbV w1 = p10 * i + p11 * w + gu1 * u + gt1 * tau;
      const CbV x1 = x + (p20 * i + p21 * w + gu2 * u + gt2 * tau);
      const CbM reverses = dir * w1 < zero;
      const CbM near = ~reverses & ((CbV)((CbM)w1 & abs_mask) < win);
      if (!any((reverses | near) & ~stuck)) {  // no sliding lane stops: the stuck ones keep w and x
        if (!any_stuck) {
          i = i1, w = w1, x = x1;
        } else {
          i = stuck ? (cb_load(P.sa + q0) * i + cb_load(P.sb + q0) * u) : i1;
          w = stuck ? w : w1;
          x = stuck ? x : x1;
        }
      } else {
        CbM sticks = reverses;
        if (any(near)) sticks |= near & ((CbV)((CbM)(kt * i1 - gravity_at(x1)) & abs_mask) <= brk);
        w1 = sticks ? zero : w1;
        i = stuck ? (cb_load(P.sa + q0) * i + cb_load(P.sb + q0) * u) : i1;
        w = stuck ? w : w1;
        x = stuck ? x : x1;
      }
      i_sum += i;
      const CbV ai = (CbV)((CbM)i & abs_mask);
      i_peak = i_peak < ai ? ai : i_peak;
    }
  }
  cb_store(P.i + q0, i), cb_store(P.w + q0, w), cb_store(P.x + q0, x), cb_store(P.ic + q0, ic);
  cb_store(P.iv + q0, iv), cb_store(P.iset + q0, iset), cb_store(P.u + q0, u);
  cb_store(P.i_sum + q0, i_sum), cb_store(P.i_peak + q0, i_peak);
  if constexpr (kOutputs) {
    // CascadeBatch::advance's sample (CascadeAxis::sample() and the end of CascadeAxis::advance), and whether every
    // state variable kept its bits.
    const CbV r = cb_load(P.r + q0), te = cb_load(P.te + q0);
    cb_store(P.o_vel + q0, r * w);
    cb_store(P.o_acc + q0, r * (w - w0) / te);
    cb_store(P.o_mean + q0, i_sum / (zero + static_cast<double>(per_te)));
    const CbM fixed = ((CbM)i == (CbM)i0) & ((CbM)w == (CbM)w0) & ((CbM)x == (CbM)x0) & ((CbM)ic == (CbM)ic0) &
                      ((CbM)iv == (CbM)iv0) & ((CbM)iset == (CbM)iset0) & ((CbM)u == (CbM)u0);
    __builtin_memcpy(P.o_fixed + q0, &fixed, sizeof fixed);
  }
}

template <bool kTrace>
void cb_periods_generic(CascadePack& P, int m, int per_te, int per_vel, InnerSample* trace) {
  for (int q0 = 0; q0 < m; q0 += 4) cb_period<kTrace, false>(P, q0, per_te, per_vel, trace, std::min(4, m - q0));
}

// The same code compiled for AVX2 (no FMA: nothing can fuse), chosen at run time.
template <bool kTrace>
__attribute__((target("avx2"))) void cb_periods_avx2(CascadePack& P, int m, int per_te, int per_vel,
                                                     InnerSample* trace) {
  for (int q0 = 0; q0 < m; q0 += 4) cb_period<kTrace, false>(P, q0, per_te, per_vel, trace, std::min(4, m - q0));
}

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

// d / te for te > 0, without the division when d is +0 (an axis at rest: its setpoint, speed or acceleration
// repeats), where the quotient is +0 exactly.
[[gnu::always_inline]] inline double cb_over_te(double d, double te) {
  return std::bit_cast<std::uint64_t>(d) == 0 ? 0.0 : d / te;
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

// CascadeBatch::run_rows, Te by Te: the NC's command and the position loop per lane (scalar: simulate.cpp's
// next_command, CascadeBatch::advance), the inner loops of the lanes that run on the slots' vectors, whose state
// stays in the pack while the same lanes run (the slots are re-filled only when that set changes: a lane reaches
// or leaves its fixed point), and the rows written per lane.
[[gnu::always_inline]] inline void cb_rows_loop(CbRows& c, long long k0, long long k1, long long base, long long n_set,
                                                long long rows, double te) {
  CascadePack& P = *c.P;
  const int n_lanes = c.n_lanes;
  int cur[CascadeBatch::kMaxLanes];  // the lanes whose state is in the slots (cur_m < 0: none)
  int cur_m = -1;
  const auto put = [&](CascadeRowLane& R, long long row, const AxisSample& s) {
    const long long r = row - base;
    R.out[0][r] = s.position;
    R.out[1][r] = s.velocity;
    R.out[2][r] = s.acceleration;
    R.out[3][r] = cb_over_te(s.acceleration - R.prev_acc, te);
    R.prev_acc = s.acceleration;
    R.out[4][r] = s.current_A;
    R.out[5][r] = s.current_mean_A;
    R.out[6][r] = s.current_peak_A;
    R.out[7][r] = s.current_setpoint_A;
  };
  if (k0 < k1)
    for (int l = 0; l < n_lanes; ++l) put(c.rl[l], k0, c.rl[l].s);
  for (long long k = k0; k < k1 && k + 1 < rows; ++k) {
    const long long ks = k < n_set ? k : n_set - 1;
    int run[CascadeBatch::kMaxLanes];
    int m = 0;
    for (int l = 0; l < n_lanes; ++l) {
      CascadeRowLane& R = c.rl[l];
      CascadeLane& L = c.lanes[l];
      CbNcLane& N = c.nc[l];
      // simulate.cpp's next_command.
      const double position = R.setpoints[ks];
      const double velocity = cb_over_te(position - R.prev_x, te);
      const double acceleration = cb_over_te(velocity - R.prev_v, te);
      R.prev_x = position, R.prev_v = velocity;
      double kv = N.kv, kf = N.kf;
      if (R.kv && !std::isnan(R.kv[ks])) kv = R.kv[ks];
      if (R.kf && !std::isnan(R.kf[ks])) kf = R.kf[ks];
      // CascadeBatch::advance's position loop.
      N.pos_line[*N.pos_head] = position;
      *N.pos_head = *N.pos_head + 1 == N.pos_n ? 0 : *N.pos_head + 1;
      const double xd = N.pos_line[*N.pos_head];
      N.vel_line[*N.ff_head] = velocity;
      N.acc_line[*N.ff_head] = acceleration;
      *N.ff_head = *N.ff_head + 1 == N.ff_n ? 0 : *N.ff_head + 1;
      const double vd = N.vel_line[*N.ff_head], ad = N.acc_line[*N.ff_head];
      int slot = -1;
      for (int j = 0; j < cur_m; ++j)
        if (cur[j] == l) slot = j;
      const double x = slot >= 0 ? P.x[slot] : L.x;
      L.w_cmd = (kv * (xd - x) + kf * vd) * L.inv_r;
      L.i_ff = L.ff_current_per_accel * ad;
      if (L.fixed && cb_same_bits(L.w_cmd, L.last_w_cmd) && cb_same_bits(L.i_ff, L.last_i_ff)) {
        R.s = L.last;
        ++*c.skipped;
        continue;
      }
      L.last_w_cmd = L.w_cmd, L.last_i_ff = L.i_ff;
      run[m++] = l;
    }
    if (m > 0) {
      if (m != cur_m || !std::equal(run, run + m, cur)) {
        if (cur_m > 0) cb_flush_state(P, c.lanes, cur, cur_m);
        if (m != *c.packed_m || !std::equal(run, run + m, c.packed)) {
          cb_pack_constants(P, c.lanes, run, m);
          std::copy(run, run + m, c.packed);
          *c.packed_m = m;
        }
        cb_load_state(P, c.lanes, run, m);
        std::copy(run, run + m, cur);
        cur_m = m;
      }
      const int slots = (m + 3) / 4 * 4;
      for (int j = 0; j < slots; ++j) {
        const CascadeLane& L = c.lanes[run[j < m ? j : 0]];
        P.w_cmd[j] = L.w_cmd, P.i_ff[j] = L.i_ff;
      }
      for (int q0 = 0; q0 < m; q0 += 4) cb_period<false, true>(P, q0, c.per_te, c.per_vel, nullptr, 0);
      for (int j = 0; j < m; ++j) {
        CascadeLane& L = c.lanes[run[j]];
        AxisSample& s = c.rl[run[j]].s;
        s.position = P.x[j];
        s.velocity = P.o_vel[j];
        s.acceleration = P.o_acc[j];
        s.current_A = P.i[j];
        s.current_mean_A = P.o_mean[j];
        s.current_peak_A = P.i_peak[j];
        s.current_setpoint_A = P.iset[j];
        L.last = s;
        L.fixed = P.o_fixed[j] != 0;
      }
    }
    if (k + 1 < k1)
      for (int l = 0; l < n_lanes; ++l) put(c.rl[l], k + 1, c.rl[l].s);
  }
  if (cur_m > 0) cb_flush_state(P, c.lanes, cur, cur_m);
}

void cb_rows_generic(CbRows& c, long long k0, long long k1, long long base, long long n_set, long long rows,
                     double te) {
  cb_rows_loop(c, k0, k1, base, n_set, rows, te);
}
__attribute__((target("avx2"))) void cb_rows_avx2(CbRows& c, long long k0, long long k1, long long base,
                                                  long long n_set, long long rows, double te) {
  cb_rows_loop(c, k0, k1, base, n_set, rows, te);
}

bool cb_use_avx2() {
  static const bool cpu = __builtin_cpu_supports("avx2");
  return cpu && !cascade_batch_generic_only();
}

}  // namespace

bool& cascade_batch_generic_only() {
  static bool generic = false;
  return generic;
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
  if (cb_use_avx2())
    cb_rows_avx2(c, k0, k1, base, n_set, rows, te);
  else
    cb_rows_generic(c, k0, k1, base, n_set, rows, te);
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
  if (cb_use_avx2())
    cb_periods_avx2<kTrace>(P, m, per_te_, per_velocity_, trace);
  else
    cb_periods_generic<kTrace>(P, m, per_te_, per_velocity_, trace);
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
