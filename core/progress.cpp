#include "core/progress.hpp"

namespace vmsim::core {

namespace {
thread_local Progress* ambient = nullptr;
}

Progress& ambient_progress() { return ambient ? *ambient : no_progress(); }

AmbientProgress::AmbientProgress(Progress& p) : previous_(ambient) { ambient = &p; }

AmbientProgress::~AmbientProgress() { ambient = previous_; }

}  // namespace vmsim::core
