#pragma once
// A result directory (vmsim run/motion/compare/... --out DIR) is replaced whole or not at all. The command writes
// into a fresh staging directory beside DIR (same parent, so a rename moves it); commit() swaps it into place
// atomically (renameat2 RENAME_EXCHANGE when DIR exists) and then removes the previous result. Until then DIR keeps
// the previous complete result untouched; an error, a signal or a kill leaves it so. A lock (flock on a hidden file
// beside DIR, released by the kernel when the process dies) makes a second run into DIR refuse, naming the process
// that holds it. Staging directories that dead processes left are removed by the next run into DIR; SIGTERM and
// SIGINT remove this process's at once (a thread waits for them) and exit with 128 + the signal's number.
#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::core {

class OutputDir {
 public:
  // Locks TARGET, removes stale staging directories, creates this run's. Refuses (core::Error) when another process
  // holds the lock, when TARGET is the current directory or holds it, when TARGET exists and is not a directory, and
  // when it is a non-empty directory vmsim did not write (no report.json, no marker): replacing it would delete
  // files that are not vmsim's. COMMAND names this run in the lock ("vmsim run").
  //
  // SIGNALS: CleanUpAndExit (the commands) installs, once per process, handlers for SIGTERM, SIGINT and SIGHUP that
  // remove every staging directory and exit with 128 + the signal. Leave (the Python module, whose interpreter owns
  // SIGINT as KeyboardInterrupt) installs nothing: an interrupted call unwinds and the destructor removes it.
  enum class Signals { CleanUpAndExit, Leave };
  OutputDir(const std::filesystem::path& target, std::string_view command, Signals signals = Signals::CleanUpAndExit);
  ~OutputDir();  // without commit(): removes the staging directory; the lock goes with the descriptor
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  // Where the command writes (the staging directory); target() is where the result will be.
  const std::filesystem::path& path() const { return staging_; }
  const std::filesystem::path& target() const { return target_; }
  // Swaps the staging directory into place, then removes the previous result. Throws on an I/O error (the previous
  // result is then still in place).
  void commit();
  bool committed() const { return committed_; }

 private:
  std::filesystem::path target_, staging_;
  int lock_fd_ = -1;
  bool committed_ = false;
};

// DIR's lock alone, for a command that adds files to an existing result directory (vmsim render writes DIR/images
// and DIR/report.html): while it is held, a run into DIR refuses, and it refuses while a run holds it (core::Error
// naming the holder: command, pid, host, start time). Released by the destructor, or by the kernel when the process
// dies.
class OutputLock {
 public:
  OutputLock(const std::filesystem::path& dir, std::string_view command);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  int fd_ = -1;
};

// Creates DIR, one level: its parent must exist (core::Error naming DIR otherwise). Directories inside a staging
// directory are made with this, never create_directories: after a signal's cleanup removed the staging directory, a
// thread still writing would bring it back through create_directories, and it would be left behind.
void create_result_subdir(const std::filesystem::path& dir);

// The marker file in every result directory OutputDir writes (hidden; what makes a later run replace it).
inline constexpr const char* kOutputMarker = ".vmsim-output";

}  // namespace vmsim::core
