#pragma once
// The actual motion of a run streamed (issue 21): the drives run in blocks of rows, and each block's response is
// consumed as it comes -- the drives' checks, the signal bins, the axes' following error, the tool-tip track -- and
// dropped, so that the 320 B per row of a whole response (eight signals of every axis) are never held. What later
// stages need whole stays: the track's tip and tip velocity (the sweeps; the tip is also the contour error's actual
// path), the commanded tip (the contour error's command), and the setpoints' move indices (the statistics per move).
// Every figure and file is the same, bit for bit, as from the whole response (sim/pipeline.hpp's simulate_motion,
// add_contour_error, track_of, sim/signals.hpp's motion_signals, sim/axis_following.hpp), at any block size.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "removal/track.hpp"
#include "sim/chain.hpp"
#include "sim/pipeline.hpp"
#include "sim/signals.hpp"

#include <Eigen/Core>

#include <optional>

namespace vmsim::sim {

struct StreamOptions {
  Eigen::Index block_rows = 65536;  // drive rows per block
  // Also the run's figures: the signal bins, the following error per axis, the drives' checks after the run and the
  // commanded tip for the contour error (a reference job's motion needs only its track).
  bool figures = true;
  double feed_scale = 1.0;  // the override the setpoints were interpolated with (the signals' programmed feed)
};

// What the blocks leave for the stages after them.
struct MotionStream {
  removal::PoseTrack track;             // the actual motion's tool-tip track (as track_of gives it)
  Eigen::MatrixXd command_tip_mm;       // figures: the commanded tip per response row
  std::optional<SignalBinner> signals;  // figures: every signal binned but the contour error
};

// Reads, interpolates and runs the job's program through the chain's drives in blocks, filling `m` in place (it
// must not move until finish_streamed_motion: the binner refers to its program and setpoints). Afterwards
// m.response holds no rows (it says the drives ran), m.interp.setpoints keeps only its move indices (its position
// has no columns; samples() still counts the setpoints), m.drive_checks and m.axis_following are complete.
// Throws core::Error as simulate_motion does.
MotionStream stream_actual_motion(const Chain& chain, Motion& m, const StreamOptions& options,
                                  core::Progress& progress);

// After the sweeps (they need the track's tip velocity, which may be released first): the contour error of the
// actual tip (the track's tip_mm, wherever it went) against the commanded one, into m.contour, and the finished
// signals into m.signals. Releases stream.command_tip_mm. Without figures, nothing.
void finish_streamed_motion(Motion& m, MotionStream& stream, const Eigen::MatrixXd& actual_tip_mm);

}  // namespace vmsim::sim
