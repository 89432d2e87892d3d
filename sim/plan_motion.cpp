#include "sim/plan_motion.hpp"

#include "core/timing.hpp"
#include "sim/chain.hpp"
#include "sim/motion_stream.hpp"
#include "sim/pipeline.hpp"

#include <utility>

namespace vmsim::sim {

PlannedMotion plan_motion(const core::Job& job, double feed_scale, core::RemovalSpec::Motion kind,
                          core::Progress& progress) {
  const double cpu0 = core::process_cpu_s();
  ChainOptions copt;
  copt.feed_scale = feed_scale;
  copt.ignore_gain_schedule = feed_scale != 1.0;  // a reference at other feeds (the run itself refuses it)
  const Chain chain(job, copt);
  Motion m;
  removal::PoseTrack track;
  PlannedMotion p;
  p.streamed = kind == core::RemovalSpec::Motion::Actual;
  if (p.streamed) {
    StreamOptions so;
    so.figures = false;
    track = stream_actual_motion(chain, m, so, progress).track;
  } else {
    m = simulate_motion(chain, kind, progress);
    track = track_of(m, job, kind);
  }
  p.samples =
      kind == core::RemovalSpec::Motion::Program ? double(track.tip_mm.rows()) : double(m.interp.setpoints.samples());
  p.turning = track.axis_per_sample.rows() > 0;
  p.sweeps = sweeps_of(job, track).sweeps;
  p.cpu_s = core::process_cpu_s() - cpu0;
  return p;
}

PlannedMotions plan_motions(const core::Job& job, double feed_scale, core::Progress& progress,
                            std::optional<PlannedMotion> own) {
  PlannedMotions out;
  out.own = own ? std::move(*own) : plan_motion(job, feed_scale, job.removal.motion, progress);
  switch (job.reference.kind) {
    case core::ReferenceSpec::Kind::Feed:
      out.reference = plan_motion(job, feed_scale * job.reference.feed_scale, job.removal.motion, progress);
      break;
    case core::ReferenceSpec::Kind::Program:
      out.reference = plan_motion(job, feed_scale, core::RemovalSpec::Motion::Program, progress);
      break;
    case core::ReferenceSpec::Kind::Job: {
      const core::Job rj = core::load_job(job.reference.job_file);
      out.reference = plan_motion(rj, 1.0, rj.removal.motion, progress);
      break;
    }
    case core::ReferenceSpec::Kind::Stock:
    case core::ReferenceSpec::Kind::None:
      break;
  }
  return out;
}

}  // namespace vmsim::sim
