#pragma once
// Progress of long runs on stderr: a bar with percentage and ETA when stderr is a terminal, one line per stage
// otherwise (logs stay readable).
#include "core/progress.hpp"

#include <chrono>
#include <string>

namespace vmsim::app {

class TerminalProgress : public core::Progress {
 public:
  explicit TerminalProgress(bool enabled = true);
  // A new stage; `total` units of work (0: a stage without a bar).
  void stage(const std::string& name, double total = 0) override;
  void update(double done) override;  // throttled: redraws at most ~10 times a second
  void done() override;               // ends the stage with its elapsed time

 private:
  bool tty_ = false, enabled_ = true;
  std::string name_;
  double total_ = 0;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace vmsim::app
