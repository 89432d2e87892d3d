// Issue 21, session 8: vmsim run's removal on flower_mold's own actual motion (bench/flower_mold/job.toml, CAMotics'
// flower_mold.nc from ../shared/data/real/cam; skipped without it) against the code before the session's changes:
// the track's sweeps against sweeps_from_track_reference (the track code before issue 21), and the cut as sim now
// makes it (one removal::cut call reporting progress between bands of rows) against the same sweeps cut in batches of
// 4096 (how sim cut them before) and against cut_reference (the kernel before issue 21), every ray bit for bit.
#include "core/job.hpp"
#include "removal/cut.hpp"
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "sim/chain.hpp"
#include "sim/pipeline.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <string>

namespace fs = std::filesystem;
using namespace vmsim;

namespace {

bool flower_same_rays(const removal::DexelGrid& a, const removal::DexelGrid& b, std::string& where) {
  std::vector<removal::Interval> x, y;
  for (int j = 0; j < a.nv(); ++j)
    for (int i = 0; i < a.nu(); ++i) {
      a.intervals(i, j, x);
      b.intervals(i, j, y);
      if (x.size() != y.size() || (!x.empty() && std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) != 0)) {
        where = "ray (" + std::to_string(i) + ", " + std::to_string(j) + ")";
        return false;
      }
    }
  return true;
}

}  // namespace

TEST(FlowerRemoval, ActualTrackSweepsAndCutEqualTheCodeBeforeBitForBit) {
  const fs::path program = fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "flower_mold.nc";
  if (!fs::exists(program)) GTEST_SKIP() << "needs " << program << " (CAMotics' flower_mold.nc in ../shared)";
  core::Job job = core::load_job(fs::path(VMSIM_SOURCE_DIR) / "bench" / "flower_mold" / "job.toml");
  job.program_file = program;
  const removal::PoseTrack track =
      sim::motion_track(sim::Chain(job), core::RemovalSpec::Motion::Actual, core::no_progress());
  ASSERT_GT(track.tip_mm.rows(), 3000000);
  ASSERT_EQ(track.tip_velocity_mm_per_s.rows(), track.tip_mm.rows()) << "the actual motion's track is a Hermite one";

  // The sweeps as vmsim run makes them, against the track code before issue 21 with the same options.
  const removal::TrackSweeps ts = sim::sweeps_of(job, track);
  const std::optional<removal::Box> box = sim::stock_box(job);
  ASSERT_TRUE(box.has_value());
  removal::TrackOptions opt;
  opt.tolerance_mm = sim::track_tolerance(job, false);
  opt.material_box = Eigen::AlignedBox3d(box->lo, box->hi);
  const removal::Tool tool = removal::make_tool(job.tool);
  const removal::TrackSweeps ref = removal::sweeps_from_track_reference(tool, track, opt);
  ASSERT_EQ(ts.sweeps.size(), ref.sweeps.size());
  EXPECT_GT(ts.sweeps.size(), 300000u);
  for (std::size_t k = 0; k < ref.sweeps.size(); ++k) {
    const removal::SweptTool &a = ts.sweeps[k], &b = ref.sweeps[k];
    ASSERT_TRUE(std::memcmp(a.tip0.data(), b.tip0.data(), 3 * sizeof(double)) == 0 &&
                std::memcmp(a.d.data(), b.d.data(), 3 * sizeof(double)) == 0 &&
                std::memcmp(a.axis.data(), b.axis.data(), 3 * sizeof(double)) == 0)
        << "sweep " << k;
  }
  EXPECT_EQ(ts.points, ref.points);
  EXPECT_EQ(ts.error_bound_mm, ref.error_bound_mm);

  // The cut on a z-map at 0.2 mm (the job's own 0.1 mm in bench/README.md's figures; coarser here to keep the
  // reference kernel's run short).
  auto zmap = [&] {
    removal::DexelGrid z = removal::make_zmap(*box, 0.2);
    removal::fill_box(z, *box);
    return z;
  };
  removal::DexelGrid now = zmap(), batched = zmap(), before = zmap();
  removal::cut(now, ts.sweeps, &core::no_progress(), 0);
  for (std::size_t b = 0; b < ts.sweeps.size(); b += 4096)
    removal::cut(batched, std::vector<removal::SweptTool>(
                              ts.sweeps.begin() + static_cast<std::ptrdiff_t>(b),
                              ts.sweeps.begin() + static_cast<std::ptrdiff_t>(std::min(ts.sweeps.size(), b + 4096))));
  removal::cut_reference(before, ts.sweeps);
  std::string where;
  EXPECT_TRUE(flower_same_rays(now, batched, where)) << "one call vs batches of 4096: " << where;
  EXPECT_TRUE(flower_same_rays(now, before, where)) << "one call vs cut_reference: " << where;
}
