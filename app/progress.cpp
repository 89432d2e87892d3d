#include "app/progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace vmsim::app {

TerminalProgress::TerminalProgress(bool enabled) : tty_(::isatty(2) != 0), enabled_(enabled) {}

void TerminalProgress::stage(const std::string& name, double total) {
  name_ = name;
  total_ = total;
  start_ = last_draw_ = std::chrono::steady_clock::now();
  if (enabled_ && !tty_) std::fprintf(stderr, "vmsim: %s ...\n", name.c_str());
}

void TerminalProgress::update(double done) {
  if (!enabled_ || !tty_ || total_ <= 0) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  const double f = std::min(1.0, std::max(0.0, done / total_));
  const double el = std::chrono::duration<double>(now - start_).count();
  const double eta = f > 0.01 ? el * (1 - f) / f : -1;
  char bar[31];
  const int fill = static_cast<int>(f * 30);
  for (int i = 0; i < 30; ++i) bar[i] = i < fill ? '#' : '.';
  bar[30] = 0;
  if (eta >= 0)
    std::fprintf(stderr, "\r%-28s [%s] %3.0f%%  ETA %5.0f s ", name_.c_str(), bar, 100 * f, eta);
  else
    std::fprintf(stderr, "\r%-28s [%s] %3.0f%%             ", name_.c_str(), bar, 100 * f);
  std::fflush(stderr);
}

void TerminalProgress::done() {
  if (!enabled_) return;
  const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  if (tty_)
    std::fprintf(stderr, "\r%-28s done in %.2f s%40s\n", name_.c_str(), el, "");
  else
    std::fprintf(stderr, "vmsim: %s done in %.2f s\n", name_.c_str(), el);
}

}  // namespace vmsim::app
