#pragma once
// Progress of long runs on stderr: a bar with percentage and ETA when stderr is a terminal, one line per stage
// otherwise (logs stay readable).
#include <chrono>
#include <string>

namespace vmsim::app {

class Progress {
 public:
  explicit Progress(bool enabled = true);
  // A new stage; `total` units of work (0: a stage without a bar).
  void stage(const std::string& name, double total = 0);
  void update(double done);  // throttled: redraws at most ~10 times a second
  void done();               // ends the stage with its elapsed time

 private:
  bool tty_ = false, enabled_ = true;
  std::string name_;
  double total_ = 0;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace vmsim::app
