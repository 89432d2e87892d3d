#pragma once
// Progress of a long library call, one convention for every caller: a call announces each stage (with its total
// work when known), reports the work done, and ends the stage. The command line draws a bar on a terminal
// (app/progress.hpp); the Python module forwards to a Python callback and turns Ctrl-C into an exception thrown
// from update(). A stage's work is in its own units (samples, sweeps, rows); only done/total is meaningful.
#include <string>

namespace vmsim::core {

class Progress {
 public:
  virtual ~Progress() = default;
  virtual void stage(const std::string& /*name*/, double /*total*/ = 0) {}
  virtual void update(double /*done*/) {}
  virtual void done() {}
};

// A Progress that reports nothing (tests, library callers that do not watch).
inline Progress& no_progress() {
  static Progress silent;
  return silent;
}

}  // namespace vmsim::core
