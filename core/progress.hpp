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
  // Whether the call should go on. Loops deep in the chain that take no Progress argument and run inside parallel
  // regions (where update() must not throw) ask this of the ambient progress below, from the calling thread only,
  // and end early when it says false; the next stage(), update() or done() then throws.
  virtual bool keep_going() { return true; }
};

// A Progress that reports nothing (tests, library callers that do not watch).
inline Progress& no_progress() {
  static Progress silent;
  return silent;
}

// The progress of the library call running on this thread, for those deep loops (the drives' simulation): a caller
// that can stop a call (the Python module on Ctrl-C) installs its Progress here for the call's duration.
Progress& ambient_progress();
class AmbientProgress {
 public:
  explicit AmbientProgress(Progress& p);
  ~AmbientProgress();
  AmbientProgress(const AmbientProgress&) = delete;
  AmbientProgress& operator=(const AmbientProgress&) = delete;

 private:
  Progress* previous_;
};

}  // namespace vmsim::core
