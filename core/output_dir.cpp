#include "core/output_dir.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/utf8.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <stdio.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

namespace vmsim::core {

namespace fs = std::filesystem;

namespace {

// ---- staging directories of this process, removed when SIGTERM or SIGINT arrives ----
// The handler only writes the signal's number to a pipe (async-signal-safe, whatever thread the kernel picks); a
// thread reading the pipe removes the staging directories and exits. A handler rather than sigwait: sigwait needs the
// signals blocked in every thread, including the ones MPI and OpenMP start before any command runs.
struct Registry {
  std::mutex mutex;
  std::vector<fs::path> staging;
  bool dying = false;  // set under the mutex by the cleanup thread: no commit() may swap after it
};
Registry& registry() {
  static Registry* r = new Registry;  // never destroyed: the cleanup thread may use it during exit
  return *r;
}
int g_pipe[2] = {-1, -1};

extern "C" void on_terminate_signal(int sig) {
  const int saved = errno;
  const unsigned char s = static_cast<unsigned char>(sig);
  [[maybe_unused]] const ssize_t n = ::write(g_pipe[1], &s, 1);
  errno = saved;
}

void cleanup_thread() {
  unsigned char sig = 0;
  while (::read(g_pipe[0], &sig, 1) != 1) {
    if (errno != EINTR) return;
  }
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  r.dying = true;
  // Other threads write on while this one cleans. Each staging directory is first renamed aside (a name the next
  // run removes too), so no new file or directory can appear in it by its path; then removed, retrying while files
  // opened before the rename are still being closed into it. (Removing it in place lost the race to writers that
  // kept adding files: the CI's KilledRunsLeaveThePreviousResultOrTheNewOne, and the test in output_dir_test.)
  for (const fs::path& p : r.staging) {
    std::error_code ec;
    const fs::path dead = p.string() + "-dead";
    const fs::path& gone = ::rename(p.c_str(), dead.c_str()) == 0 ? dead : p;
    for (int pass = 0; pass < 50; ++pass) {
      fs::remove_all(gone, ec);
      if (!fs::exists(fs::symlink_status(gone, ec))) break;
      ::usleep(2000);
    }
    fs::remove_all(p, ec);  // in case a create_directories brought it back before the rename
  }
  ::_exit(128 + sig);
}

void install_signal_cleanup() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (::pipe2(g_pipe, O_CLOEXEC) != 0)
      throw Error(std::string("cannot set up signal handling: ") + std::strerror(errno));
    std::thread(cleanup_thread).detach();
    struct sigaction sa {};
    sa.sa_handler = on_terminate_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    for (int s : {SIGTERM, SIGINT, SIGHUP}) ::sigaction(s, &sa, nullptr);
  });
}

// Creates staging directory P and registers it, under the mutex: once the cleanup thread has begun (dying), no
// staging directory can appear that it would not remove.
void create_staging(const fs::path& target, const fs::path& p) {
  std::lock_guard<std::mutex> lock(registry().mutex);
  if (registry().dying) throw Error(target.string() + ": interrupted by a signal before writing began");
  std::error_code ec;
  if (!fs::create_directory(p, ec) || ec)
    throw Error(fmt::format("{}: cannot create the staging directory {}: {}", target.string(), p.string(),
                            ec ? ec.message() : "it exists"));
  registry().staging.push_back(p);
}
void unregister_staging(const fs::path& p) {
  std::lock_guard<std::mutex> lock(registry().mutex);
  auto& v = registry().staging;
  v.erase(std::remove(v.begin(), v.end(), p), v.end());
}

std::string random_hex() {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  return fmt::format("{:012x}", rng() & 0xffffffffffffULL);
}

std::string hostname() {
  char h[256] = {};
  if (::gethostname(h, sizeof h - 1) != 0) return "?";
  return h;
}

std::string now_utc() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

// The staging directories of TARGET start with this (hidden, beside it).
std::string staging_prefix(const fs::path& target) {
  return fmt::format(".{}.vmsim-staging-", target.filename().string());
}

// Whether DIR holds a result vmsim wrote (the marker, or report.json of a version before the marker), or nothing.
// Returns the first foreign entry's name when it holds something else.
std::string foreign_entry(const fs::path& dir) {
  std::error_code ec;
  if (fs::exists(dir / kOutputMarker, ec) || fs::exists(dir / "report.json", ec)) return {};
  for (const auto& e : fs::directory_iterator(dir, ec)) return e.path().filename().string();
  return {};
}

// renameat2 with flags; returns errno (0 on success).
int rename2(const fs::path& from, const fs::path& to, unsigned flags) {
  return ::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), flags) == 0 ? 0 : errno;
}

// Takes TARGET's lock (a hidden file beside it, never removed: removing it would let two runs lock two files) and
// writes who holds it into the file; returns the descriptor, which holds the lock until closed. HINT ends the refusal.
int lock_output_dir(const fs::path& target, std::string_view command, std::string_view hint) {
  const fs::path lock_file = target.parent_path() / fmt::format(".{}.vmsim-lock", target.filename().string());
  const int fd = ::open(lock_file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) throw Error(fmt::format("{}: cannot open the lock file: {}", lock_file.string(), std::strerror(errno)));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    char holder[512] = {};
    [[maybe_unused]] const ssize_t n = ::pread(fd, holder, sizeof holder - 1, 0);
    ::close(fd);
    std::string who(holder);
    while (!who.empty() && (who.back() == '\n' || who.back() == ' ')) who.pop_back();
    if (err == EWOULDBLOCK)
      throw Error(fmt::format("{}: another process is writing this output directory ({}); {}", target.string(),
                              who.empty() ? "unknown" : who, hint));
    throw Error(fmt::format("{}: cannot lock {}: {}", target.string(), lock_file.string(), std::strerror(err)));
  }
  const std::string me =
      fmt::format("{} (pid {} on {}, since {})\n", command, static_cast<long>(::getpid()), hostname(), now_utc());
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, me.data(), me.size(), 0) != static_cast<ssize_t>(me.size())) {
    // The lock holds without the note; only a second run's message loses the holder's name.
  }
  return fd;
}

// TARGET made absolute and normal, without a trailing slash ("out/" -> "out"), as the lock file is named from it.
fs::path normal_target(const fs::path& target) {
  std::error_code ec;
  fs::path t = fs::absolute(target, ec).lexically_normal();
  if (ec) throw Error(target.string() + ": cannot resolve the output directory: " + ec.message());
  if (!t.has_filename()) t = t.parent_path();
  return t;
}

}  // namespace

OutputDir::OutputDir(const fs::path& target, std::string_view command, Signals signals) {
  std::error_code ec;
  const fs::path t = normal_target(target);
  require_utf8_path(t, "the output directory");
  if (t == t.root_path()) throw Error(t.string() + ": cannot be an output directory (vmsim replaces it whole)");
  // The current directory (or one holding it) cannot be swapped out from under the shell that stands in it.
  const fs::path cwd = fs::current_path(ec);
  const fs::path canon = fs::weakly_canonical(t, ec);
  if (!cwd.empty()) {
    const auto rel = fs::weakly_canonical(cwd, ec).lexically_relative(canon);
    if (!rel.empty() && *rel.begin() != "..")
      throw Error(
          fmt::format("{}: is the current directory or holds it; vmsim writes a result directory whole and "
                      "replaces it whole: give another --out (a new directory, or an earlier result)",
                      t.string()));
  }
  target_ = t;
  const fs::path parent = target_.parent_path();
  fs::create_directories(parent, ec);
  if (ec) throw Error(parent.string() + ": cannot create the directory for " + target_.string() + ": " + ec.message());

  lock_fd_ = lock_output_dir(target_, command, "wait for it to end or give another --out");

  try {
    if (fs::exists(target_, ec)) {
      if (!fs::is_directory(target_, ec))
        throw Error(target_.string() + ": exists and is not a directory; give --out a directory");
      const std::string foreign = foreign_entry(target_);
      if (!foreign.empty())
        throw Error(
            fmt::format("{}: holds files vmsim did not write (e.g. {}); vmsim replaces its output directory "
                        "whole, which would delete them: give --out a new or empty directory, or an earlier "
                        "result of vmsim",
                        target_.string(), foreign));
    }
    // Staging directories left by dead processes: this process holds the lock, so no live one owns them.
    const std::string prefix = staging_prefix(target_);
    for (const auto& e : fs::directory_iterator(parent, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind(prefix, 0) == 0) {
        std::error_code rec;
        fs::remove_all(e.path(), rec);
      }
    }
    if (signals == Signals::CleanUpAndExit) install_signal_cleanup();
    staging_ = parent / (prefix + std::to_string(::getpid()) + "-" + random_hex());
    create_staging(target_, staging_);
    write_file_atomic(staging_ / kOutputMarker, std::string(command) + "\n");
  } catch (...) {
    if (!staging_.empty()) {
      fs::remove_all(staging_, ec);
      unregister_staging(staging_);
    }
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw;
  }
}

OutputDir::~OutputDir() {
  if (!staging_.empty()) {
    std::error_code ec;
    if (!committed_) fs::remove_all(staging_, ec);
    unregister_staging(staging_);
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

void OutputDir::commit() {
  if (committed_) return;
  fsync_directory(staging_);
  const fs::path parent = target_.parent_path();
  {
    std::lock_guard<std::mutex> lock(registry().mutex);
    if (registry().dying) throw Error(target_.string() + ": interrupted by a signal; the previous result is kept");
    std::error_code ec;
    const bool exists = fs::exists(fs::symlink_status(target_, ec));
    int err;
    if (exists) {
      err = rename2(staging_, target_, RENAME_EXCHANGE);
      if (err == EINVAL || err == ENOSYS) {
        // A file system without RENAME_EXCHANGE: the previous result goes to a staging name first (cleaned by the
        // next run if this one dies in between), then the new one takes its place. Never mixed; for an instant absent.
        const fs::path old = parent / (staging_prefix(target_) + std::to_string(::getpid()) + "-old-" + random_hex());
        if (::rename(target_.c_str(), old.c_str()) != 0) {
          err = errno;
        } else if (::rename(staging_.c_str(), target_.c_str()) != 0) {
          err = errno;
          [[maybe_unused]] const int back = ::rename(old.c_str(), target_.c_str());
        } else {
          err = 0;
          registry().staging.push_back(old);
          fs::remove_all(old, ec);
          auto& v = registry().staging;
          v.erase(std::remove(v.begin(), v.end(), old), v.end());
        }
      }
    } else {
      err = rename2(staging_, target_, RENAME_NOREPLACE);
      if (err == EINVAL || err == ENOSYS) err = ::rename(staging_.c_str(), target_.c_str()) == 0 ? 0 : errno;
    }
    if (err != 0)
      throw Error(fmt::format("{}: cannot move the finished result into place (from {}): {}", target_.string(),
                              staging_.string(), std::strerror(err)));
    committed_ = true;
  }
  fsync_directory(parent);
  // After the exchange the staging name holds the previous result; a failure here leaves it for the next run.
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void create_result_subdir(const fs::path& dir) {
  std::error_code ec;
  fs::create_directory(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create the directory: " + ec.message());
}

OutputLock::OutputLock(const fs::path& dir, std::string_view command) {
  const fs::path t = normal_target(dir);
  std::error_code ec;
  if (!fs::is_directory(t, ec)) throw Error(t.string() + ": is not a directory");
  fd_ = lock_output_dir(t, command, "wait for it to end, then run this again");
}

OutputLock::~OutputLock() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace vmsim::core
