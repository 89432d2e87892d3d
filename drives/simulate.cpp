#include "drives/simulate.hpp"

#include "core/error.hpp"
#include "core/progress.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/cascade_batch.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace vmsim::drives {

namespace {

using Index = Eigen::Index;

// Everything one axis needs, prepared before the parallel region (nothing in it allocates or throws), and the
// state it carries from one block of rows to the next (BlockSimulation).
struct AxisJob {
  std::optional<CascadeAxis> model;  // empty: an axis without a drive that never moves (it holds its position)
  std::unique_ptr<AxisModel> other;  // instead of the cascade: SimulateOptions::axis_models
  const double* kv = nullptr;        // this axis' column of the gain schedule (setpoint rows), or null
  const double* kf = nullptr;
  std::vector<InnerSample> inner;  // one Te of current-loop samples, for the full-rate trace
  AxisSample s;                    // the state at the next row's instant
  double prev_x = 0.0, prev_v = 0.0;  // the NC's previous setpoint and velocity (at rest before the first one)
  double prev_acc = 0.0;              // the previous row's acceleration (the jerk's backward difference)
  bool started = false;
};

// The NC's command for setpoint row ks (position x_d): the feedforward set points are backward differences of the
// position setpoints; the gain schedule's row when there is one.
AxisCommand next_command(AxisJob& job, double position, Index ks, double te) {
  AxisCommand c;
  c.position = position;
  c.velocity = (c.position - job.prev_x) / te;
  c.acceleration = (c.velocity - job.prev_v) / te;
  job.prev_x = c.position;
  job.prev_v = c.velocity;
  if (job.kv) c.kv_per_s = job.kv[ks];
  if (job.kf) c.kf = job.kf[ks];
  return c;
}

// An axis' first row: at rest (its model's resting state, or held at x0 without a cascade), the NC's previous
// setpoint x0 and velocity and acceleration zero.
void start_axis(AxisJob& job, double x0) {
  if (job.started) return;
  if (job.model)
    job.s = job.model->sample();
  else
    job.s.position = x0;
  job.prev_x = x0, job.prev_v = 0.0, job.prev_acc = 0.0;
  job.started = true;
}

// An axis' response columns in a block, and where its setpoints are.
struct ResponseColumns {
  double *position, *velocity, *acceleration, *jerk, *current, *current_mean, *current_peak, *current_setpoint;
  const double* setpoints;

  ResponseColumns() = default;
  ResponseColumns(AxisResponse& out, const Eigen::MatrixXd& setpoints_all, Index axis)
      : position(out.position.col(axis).data()),
        velocity(out.velocity.col(axis).data()),
        acceleration(out.acceleration.col(axis).data()),
        jerk(out.jerk.col(axis).data()),
        current(out.current_A.col(axis).data()),
        current_mean(out.current_mean_A.col(axis).data()),
        current_peak(out.current_peak_A.col(axis).data()),
        current_setpoint(out.current_setpoint_A.col(axis).data()),
        setpoints(setpoints_all.col(axis).data()) {}

  // Row r is the axis' sample s; the jerk is the backward difference of the accelerations (at rest before row 0).
  void put(Index r, const AxisSample& s, AxisJob& job, double te) const {
    position[r] = s.position;
    velocity[r] = s.velocity;
    acceleration[r] = s.acceleration;
    current[r] = s.current_A;
    current_mean[r] = s.current_mean_A;
    current_peak[r] = s.current_peak_A;
    current_setpoint[r] = s.current_setpoint_A;
    jerk[r] = (s.acceleration - job.prev_acc) / te;
    job.prev_acc = s.acceleration;
  }
};

// One current-loop sample into the full-rate trace at sample `at`.
void put_inner(FullRateTrace& t, Index at, const InnerSample& q) {
  t.position[at] = q.position;
  t.velocity[at] = q.velocity;
  t.current_A[at] = q.current_A;
  t.current_setpoint_A[at] = q.current_setpoint_A;
  t.voltage_V[at] = q.voltage_V;
}

// One axis from its setpoint column to its response columns. Row k of the response is the axis at t = k*Te, the
// instant setpoint k is sent: row 0 is the resting state after reset, row k+1 the state after the drive has worked
// on setpoint k for one Te. Beyond the last setpoint the NC holds it (and its last gains) for the settling rows.
// Asked every kPollRows rows whether to go on (core::Progress::keep_going), on the calling thread only; every axis
// stops when it says no (the caller's progress then throws).
struct Stop {
  core::Progress* progress = nullptr;
  std::thread::id caller;
  std::atomic<bool> requested{false};
  bool go() {
    if (std::this_thread::get_id() == caller && !progress->keep_going())
      requested.store(true, std::memory_order_relaxed);
    return !requested.load(std::memory_order_relaxed);
  }
};
constexpr Index kPollRows = 256;  // ~ a few ms of one axis: Ctrl-C is seen within ~0.1 s

// Rows [k0, k1) of `rows` into out's rows [0, k1 - k0); the trace (whole run) at its absolute samples. The state
// carried in `job` makes consecutive calls the same, bit for bit, as one call over all rows.
void run_axis(AxisJob& job, const Eigen::MatrixXd& setpoints, Index axis, double te, Index k0, Index k1, Index rows,
              AxisResponse& out, FullRateTrace* trace, Stop& stop) {
  const Index n_set = setpoints.rows();
  const double x0 = setpoints(0, axis);
  if (!job.model && !job.other) {
    out.position.col(axis).setConstant(x0);
    for (Eigen::MatrixXd* m : {&out.velocity, &out.acceleration, &out.jerk, &out.current_A, &out.current_setpoint_A,
                               &out.current_mean_A, &out.current_peak_A})
      m->col(axis).setZero();
    return;
  }
  AxisModel& m = job.other ? *job.other : static_cast<AxisModel&>(*job.model);
  if (job.other) trace = nullptr;
  std::vector<InnerSample>& inner = job.inner;
  const Index nin = job.model ? job.model->inner_steps() : 0;

  AxisSample& s = job.s;
  start_axis(job, x0);
  const ResponseColumns cols(out, setpoints, axis);
  for (Index k = k0; k < k1; ++k) {
    if ((k - k0) % kPollRows == 0 && !stop.go()) return;
    cols.put(k - k0, s, job, te);
    if (k + 1 == rows) break;
    const Index ks = k < n_set ? k : n_set - 1;
    const AxisCommand c = next_command(job, cols.setpoints[ks], ks, te);
    if (trace) {
      s = job.model->step(c, inner.data());
      for (Index n = 0; n < nin; ++n) put_inner(*trace, k * nin + n, inner[static_cast<std::size_t>(n)]);
    } else {
      s = m.step(c);
    }
  }
  if (trace && k1 == rows) put_inner(*trace, (rows - 1) * nin, job.model->inner_sample());  // the last row's instant
}

// Several cascade axes (a group of CascadeBatch::compatible ones) over rows [k0, k1): the same rows, commands and
// trace as run_axis gives each of them, bit for bit (CascadeBatch steps each axis as CascadeAxis::step does).
void run_batch(const std::vector<AxisJob*>& group, const std::vector<Index>& axis_of, const Eigen::MatrixXd& setpoints,
               double te, Index k0, Index k1, Index rows, AxisResponse& out, std::vector<FullRateTrace>* traces,
               Stop& stop) {
  const Index n_set = setpoints.rows();
  const int lanes = static_cast<int>(group.size());
  std::vector<CascadeAxis*> axes;
  for (AxisJob* job : group) axes.push_back(&*job->model);
  CascadeBatch batch(axes, traces != nullptr);
  const Index nin = axes.front()->inner_steps();
  AxisCommand commands[CascadeBatch::kMaxLanes];
  AxisSample samples[CascadeBatch::kMaxLanes];
  // Each lane's output columns and setpoint column, looked up once (the loop stores through them).
  ResponseColumns cols[CascadeBatch::kMaxLanes];
  for (int l = 0; l < lanes; ++l) {
    const Index axis = axis_of[static_cast<std::size_t>(l)];
    AxisJob& job = *group[static_cast<std::size_t>(l)];
    start_axis(job, setpoints(0, axis));
    samples[l] = job.s;
    cols[l] = ResponseColumns(out, setpoints, axis);
  }
  if (!traces) {
    // The rows in runs of kPollRows, the batch keeping its lanes' state in its vectors within a run.
    CascadeRowLane rl[CascadeBatch::kMaxLanes];
    for (int l = 0; l < lanes; ++l) {
      AxisJob& job = *group[static_cast<std::size_t>(l)];
      const ResponseColumns& c = cols[l];
      rl[l].setpoints = c.setpoints;
      rl[l].kv = job.kv, rl[l].kf = job.kf;
      double* o[8] = {c.position, c.velocity,     c.acceleration, c.jerk,
                      c.current,  c.current_mean, c.current_peak, c.current_setpoint};
      std::copy(o, o + 8, rl[l].out);
      rl[l].s = job.s, rl[l].prev_x = job.prev_x, rl[l].prev_v = job.prev_v, rl[l].prev_acc = job.prev_acc;
    }
    for (Index c0 = k0; c0 < k1; c0 += kPollRows) {
      if (!stop.go()) break;
      batch.run_rows(rl, c0, std::min(k1, c0 + kPollRows), k0, n_set, rows, te);
    }
    batch.store();
    for (int l = 0; l < lanes; ++l) {
      AxisJob& job = *group[static_cast<std::size_t>(l)];
      job.s = rl[l].s, job.prev_x = rl[l].prev_x, job.prev_v = rl[l].prev_v, job.prev_acc = rl[l].prev_acc;
    }
    return;
  }
  Index k = k0;
  for (; k < k1; ++k) {
    if ((k - k0) % kPollRows == 0 && !stop.go()) break;
    for (int l = 0; l < lanes; ++l) cols[l].put(k - k0, samples[l], *group[static_cast<std::size_t>(l)], te);
    if (k + 1 == rows) break;
    const Index ks = k < n_set ? k : n_set - 1;
    for (int l = 0; l < lanes; ++l)
      commands[l] = next_command(*group[static_cast<std::size_t>(l)], cols[l].setpoints[ks], ks, te);
    batch.step(commands, samples);
    if (traces)
      for (int l = 0; l < lanes; ++l) {
        FullRateTrace& t = (*traces)[static_cast<std::size_t>(axis_of[static_cast<std::size_t>(l)])];
        const InnerSample* q = batch.trace(l);
        for (Index n = 0; n < nin; ++n) put_inner(t, k * nin + n, q[n]);
      }
  }
  batch.store();
  for (int l = 0; l < lanes; ++l) group[static_cast<std::size_t>(l)]->s = samples[l];
  if (traces && k1 == rows && k + 1 == rows)  // the last row's instant closes the trace
    for (int l = 0; l < lanes; ++l)
      put_inner((*traces)[static_cast<std::size_t>(axis_of[static_cast<std::size_t>(l)])], (rows - 1) * nin,
                group[static_cast<std::size_t>(l)]->model->inner_sample());
}

}  // namespace

Eigen::VectorXd simulate_axis(AxisModel& m, const Eigen::VectorXd& setpoints, double te, Eigen::Index rows) {
  if (setpoints.size() == 0 || rows < 1) throw core::Error("simulate_axis: no setpoints or no rows");
  Eigen::VectorXd y(rows);
  y[0] = setpoints[0];
  double prev_x = setpoints[0], prev_v = 0.0;
  for (Index k = 0; k + 1 < rows; ++k) {
    AxisCommand c;
    c.position = setpoints[std::min<Index>(k, setpoints.size() - 1)];
    c.velocity = (c.position - prev_x) / te;
    c.acceleration = (c.velocity - prev_v) / te;
    prev_x = c.position;
    prev_v = c.velocity;
    y[k + 1] = m.step(c).position;
  }
  return y;
}

struct BlockSimulation::Impl {
  const core::Setpoints* setpoints = nullptr;
  double te = 1e-3;
  Index rows = 0, next = 0;
  std::vector<std::string> axis_names;
  std::vector<AxisJob> jobs;
  bool full_rate_trace = false;
  std::vector<FullRateTrace> trace;  // whole run, per axis, when full_rate_trace
  // The units of work, each run by one thread: a group of cascade axes stepped together (CascadeBatch), or one
  // other axis on its own (run_axis).
  struct Work {
    std::vector<Index> axes;
    bool batch = false;
  };
  std::vector<Work> work;

  Impl(const core::Setpoints& setpoints, const core::Machine& machine, const SimulateOptions& options);
  // Rows [next, k1) into `out` (sized for them), then next = k1.
  void run(Index k1, AxisResponse& out);
  void plan_work();
};

BlockSimulation::Impl::Impl(const core::Setpoints& setpoints, const core::Machine& machine,
                            const SimulateOptions& options)
    : setpoints(&setpoints) {
  const std::string& file = machine.source_file;
  const Index n_axes = static_cast<Index>(machine.axes.size());
  const double te = setpoints.period_s;
  if (!(te > 0.0 && std::isfinite(te)))
    throw core::Error(fmt::format("setpoints: the period Te must be positive, found {}", te));
  if (setpoints.samples() == 0) throw core::Error("setpoints: no samples to simulate");
  if (setpoints.position.cols() != n_axes)
    throw core::Error(core::located(
        file, 0, fmt::format("the setpoints have {} axes, the machine {}", setpoints.position.cols(), n_axes)));
  if (!setpoints.axis_names.empty()) {
    for (Index a = 0; a < n_axes; ++a)
      if (static_cast<std::size_t>(a) >= setpoints.axis_names.size() ||
          setpoints.axis_names[static_cast<std::size_t>(a)] != machine.axes[static_cast<std::size_t>(a)].name)
        throw core::Error(core::located(file, 0, "the setpoints' axes are not the machine's axes in its order"));
  }
  if (!setpoints.position.allFinite()) throw core::Error("setpoints: a position is not finite");
  if (!(options.settle_s >= 0.0 && std::isfinite(options.settle_s)))
    throw core::Error(fmt::format("settle_s must be >= 0, found {}", options.settle_s));

  const Index n_set = setpoints.samples();
  rows = n_set + static_cast<Index>(std::llround(options.settle_s / te));
  this->te = te;

  const GainSchedule* g = options.gains;
  const auto check_schedule = [&](const Eigen::MatrixXd& m, const char* what) {
    if (m.size() == 0) return false;
    if (m.rows() != n_set || m.cols() != n_axes)
      throw core::Error(
          fmt::format("gain schedule {}: {} x {}, expected one row per setpoint and a column per axis "
                      "({} x {})",
                      what, m.rows(), m.cols(), n_set, n_axes));
    for (Index i = 0; i < m.size(); ++i) {
      const double v = m.data()[i];
      if (!std::isnan(v) && !(std::isfinite(v) && v >= 0.0))
        throw core::Error(
            fmt::format("gain schedule {}: {} at row {} is not a gain (expected >= 0, or NaN for the "
                        "drive's own)",
                        what, v, i % m.rows()));
    }
    return true;
  };
  const bool have_kv = g && check_schedule(g->kv_per_s, "kv_per_s");
  const bool have_kf = g && check_schedule(g->kf, "kf");
  if (have_kv && (g->kv_per_s.array() == 0.0).any()) throw core::Error("gain schedule kv_per_s: Kv must be > 0");

  for (const auto& ax : machine.axes) axis_names.push_back(ax.name);
  jobs.resize(static_cast<std::size_t>(n_axes));
  full_rate_trace = options.full_rate_trace;
  if (options.full_rate_trace) trace.resize(static_cast<std::size_t>(n_axes));
  for (Index a = 0; a < n_axes; ++a) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(a)];
    AxisJob& job = jobs[static_cast<std::size_t>(a)];
    const bool moves = (setpoints.position.col(a).array() != setpoints.position(0, a)).any();
    const AxisModel* proto = options.axis_models && static_cast<std::size_t>(a) < options.axis_models->size()
                                 ? (*options.axis_models)[static_cast<std::size_t>(a)]
                                 : nullptr;
    if (proto) {
      job.other = proto->clone();
      job.other->reset(setpoints.position(0, a));
      if (have_kv) job.kv = g->kv_per_s.col(a).data();
      if (have_kf) job.kf = g->kf.col(a).data();
      continue;
    }
    if (!ax.drive) {
      if (moves)
        throw core::Error(core::located(
            file, 0,
            fmt::format("axis {} moves but has no [axes.drive] section: its drive cannot be simulated (add the "
                        "drive parameters, see parts/README.md)",
                        ax.name)));
      continue;
    }
    try {
      job.model.emplace(*ax.drive, te, ax.kind);
      job.model->reset(setpoints.position(0, a));
    } catch (const core::Error& e) {
      throw core::Error(core::located(file, 0, fmt::format("axis {} [axes.drive]: {}", ax.name, e.what())));
    }
    if (have_kv) job.kv = g->kv_per_s.col(a).data();
    if (have_kf) job.kf = g->kf.col(a).data();
    if (options.full_rate_trace) {
      FullRateTrace& t = trace[static_cast<std::size_t>(a)];
      t.period_s = ax.drive->current_period_s;
      job.inner.resize(static_cast<std::size_t>(job.model->inner_steps()));
      const Index n = (rows - 1) * job.model->inner_steps() + 1;
      for (Eigen::ArrayXd* v : {&t.position, &t.velocity, &t.current_A, &t.current_setpoint_A, &t.voltage_V})
        v->setZero(n);
    }
  }
  plan_work();
}

// Cascade axes with the same loop periods go into one batch (up to CascadeBatch::kMaxLanes): one thread steps them
// all, which costs less CPU than an axis per thread (the batch overlaps their latency-bound chains, threads only
// add their hand-over). Every other axis is a unit of its own.
void BlockSimulation::Impl::plan_work() {
  work.clear();
  for (Index a = 0; a < static_cast<Index>(jobs.size()); ++a) {
    const AxisJob& job = jobs[static_cast<std::size_t>(a)];
    if (!job.model || job.other) {
      work.push_back(Work{{a}, false});
      continue;
    }
    Work* into = nullptr;
    for (Work& w : work)
      if (w.batch && static_cast<int>(w.axes.size()) < CascadeBatch::kMaxLanes &&
          CascadeBatch::compatible(*jobs[static_cast<std::size_t>(w.axes.front())].model, *job.model))
        into = &w;
    if (into)
      into->axes.push_back(a);
    else
      work.push_back(Work{{a}, true});
  }
}

void BlockSimulation::Impl::run(Index k1, AxisResponse& out) {
  const Index k0 = next;
  const Index n_axes = static_cast<Index>(jobs.size());
  out.period_s = te;
  out.axis_names = axis_names;
  // Sized, not zeroed: every unit of work writes every row of its axes' columns (an axis without a drive its zeros),
  // and a stopped run returns no response.
  for (Eigen::MatrixXd* m : {&out.position, &out.velocity, &out.acceleration, &out.jerk, &out.current_A,
                             &out.current_setpoint_A, &out.current_mean_A, &out.current_peak_A})
    m->resize(k1 - k0, n_axes);
  // Axes are independent (no coupling in the model, the feed-drive simulation paper section 2.2): each thread runs
  // whole units of work (a batch or an axis), writing only their columns, so the results do not depend on the thread
  // count or the schedule.
  const int n = static_cast<int>(work.size());
  Stop stop;
  stop.progress = &core::ambient_progress();
  stop.caller = std::this_thread::get_id();
  std::atomic<int> next_unit{0}, units_done{0};
  const auto run_unit = [&](const Work& w) {
    if (w.batch) {
      std::vector<AxisJob*> group;
      for (Index a : w.axes) group.push_back(&jobs[static_cast<std::size_t>(a)]);
      run_batch(group, w.axes, setpoints->position, te, k0, k1, rows, out, full_rate_trace ? &trace : nullptr, stop);
    } else {
      const Index a = w.axes.front();
      AxisJob& job = jobs[static_cast<std::size_t>(a)];
      FullRateTrace* t = full_rate_trace && job.model && !job.other ? &trace[static_cast<std::size_t>(a)] : nullptr;
      run_axis(job, setpoints->position, a, te, k0, k1, rows, out, t, stop);
    }
  };
  if (n == 1) {
    run_unit(work.front());  // no thread to share with: no parallel region
  } else {
#pragma omp parallel
    {
      // Each thread takes the next unit until none is left (as schedule(dynamic, 1) would).
      for (int u = next_unit++; u < n; u = next_unit++) {
        run_unit(work[static_cast<std::size_t>(u)]);
        ++units_done;
      }
      // The calling thread, out of units, keeps asking its caller while the others finish theirs.
      if (std::this_thread::get_id() == stop.caller && stop.progress != &core::no_progress())
        while (units_done.load() < n) {
          stop.go();
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
    }
  }
  // Stopped by the caller: its progress throws (the response is incomplete and is not returned).
  if (stop.requested) stop.progress->update(0);
  if (stop.requested) throw core::Error("the drives' simulation was stopped by its caller");
  next = k1;
}

BlockSimulation::BlockSimulation(const core::Setpoints& setpoints, const core::Machine& machine,
                                 const SimulateOptions& options)
    : impl_(std::make_unique<Impl>(setpoints, machine, options)) {
  if (options.full_rate_trace)
    throw core::Error("the drives' simulation in blocks keeps no full-rate trace (simulate_axes does)");
}
BlockSimulation::~BlockSimulation() = default;
BlockSimulation::BlockSimulation(BlockSimulation&&) noexcept = default;
BlockSimulation& BlockSimulation::operator=(BlockSimulation&&) noexcept = default;

Eigen::Index BlockSimulation::rows() const { return impl_->rows; }
Eigen::Index BlockSimulation::next_row() const { return impl_->next; }

AxisResponse BlockSimulation::next(Eigen::Index block_rows) {
  if (block_rows < 1) throw core::Error(fmt::format("drives: a block of {} rows (expected >= 1)", block_rows));
  AxisResponse out;
  impl_->run(std::min(impl_->rows, impl_->next + block_rows), out);
  return out;
}

AxisResponse simulate_axes(const core::Setpoints& setpoints, const core::Machine& machine,
                           const SimulateOptions& options) {
  BlockSimulation::Impl sim(setpoints, machine, options);
  AxisResponse out;
  sim.run(sim.rows, out);
  out.trace = std::move(sim.trace);
  return out;
}

}  // namespace vmsim::drives
