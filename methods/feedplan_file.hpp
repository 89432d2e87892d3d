#pragma once
// Feed plans as files (Chen et al. 2016's contour-error-constrained feed plan): `vmsim plan-feed` writes one, `vmsim
// run` (and every command that interpolates the job, through sim::Chain) follows it through the job's `feed_plan` key
// (parts/README.md).
//
// Format (CSV, '#' lines first):
//   # vmsim feed plan 1: a feed ceiling along the path the interpolator follows (Chen et al. 2016, vmsim plan-feed)
//   # job=NAME                 the job it was planned for (information)
//   # period_s=0.004           Te of the interpolation it was planned for (checked)
//   # path_length_mm=382.93    arc length of the smoothed path the interpolator follows (checked within 1e-6 mm)
//   # points=7659              the lines that follow (checked)
//   # follow=1                 only in a profile to be followed as given (motion::FeedCeiling::follow): its first and
//                              last feed (and single points between, such as a cusp) may be 0
//   # ...                      free comment lines
//   s_mm,feed_ceiling_mm_per_s,x_mm,y_mm,z_mm
//   one line per ceiling point: s along the smoothed path (motion::smooth_path_for), strictly increasing; the ceiling
//   (mm/s, > 0; the squared ceiling is linear in s between the points, motion::FeedCeiling); the path's point at s
//   (checked against the job's own path within 1e-6 mm, so that a plan is never applied to another path).
#include "motion/interp.hpp"
#include "motion/smooth_path.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::methods {

// Written atomically; s and the ceiling with 17 significant digits (read back bit for bit), the points to 1 nm.
// `path`: the smoothed path the ceiling's s is measured along. `comments`: extra '#' lines.
void write_feed_plan(const std::filesystem::path& file, const motion::FeedCeiling& ceiling,
                     const motion::SmoothPath& path, double period_s, const std::string& job_name,
                     const std::vector<std::string>& comments = {});

// Reads a plan and checks it against the path it is to be followed along and the interpolation period. Throws
// core::Error naming the file (and the line) and what was expected.
motion::FeedCeiling read_feed_plan(const std::filesystem::path& file, const motion::SmoothPath& path, double period_s);

}  // namespace vmsim::methods
