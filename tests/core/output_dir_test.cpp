// core/output_dir and core/atomic_file: a result directory is replaced whole or not at all, a second writer is
// refused, what dead processes left is cleaned, and temporary files never follow a planted symlink. The reference is
// the file system itself, read back with std::filesystem (names, contents, which directories exist).
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/utf8.hpp"

#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>

namespace fs = std::filesystem;
using vmsim::core::AtomicFile;
using vmsim::core::Error;
using vmsim::core::OutputDir;

namespace {

struct Scratch {
  fs::path dir;
  Scratch() {
    std::random_device rd;
    dir = fs::temp_directory_path() / ("vmsim_outdir_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void put(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

// Every name in DIR (not recursive).
std::set<std::string> names(const fs::path& dir) {
  std::set<std::string> n;
  for (const auto& e : fs::directory_iterator(dir)) n.insert(e.path().filename().string());
  return n;
}

// An error's message, or "" when F does not throw core::Error.
template <class F>
std::string output_dir_error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// The signal tests' directory. A threadsafe death test (a fresh process each: the handler and its thread are set up
// once a process) re-runs the test's body from the start in its child; the child finds the parent's directory through
// the environment, and skips what only the parent does (setting up, checking).
struct SignalScratch {
  fs::path dir;
  bool child = false;
  explicit SignalScratch(const std::string& name) {
    const char* inherited = std::getenv("VMSIM_SIGNAL_TEST_DIR");
    child = inherited != nullptr;
    dir = child ? fs::path(inherited)
                : fs::temp_directory_path() / ("vmsim_signal_" + name + "_" + std::to_string(::getpid()));
    if (child) return;
    fs::remove_all(dir);
    fs::create_directories(dir);
    ::setenv("VMSIM_SIGNAL_TEST_DIR", dir.c_str(), 1);
  }
  ~SignalScratch() {
    if (child) return;
    ::unsetenv("VMSIM_SIGNAL_TEST_DIR");
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  // The first staging directory of out left in DIR, or "".
  std::string staging_left() const {
    for (const std::string& n : names(dir))
      if (n.find(".out.vmsim-staging-") != std::string::npos) return n;
    return "";
  }
};

std::string fmt_name(int writer, long i) { return "w" + std::to_string(writer) + "_" + std::to_string(i % 50); }

}  // namespace

TEST(OutputDir, CommitCreatesTheTargetAndLeavesNoStaging) {
  Scratch s;
  const fs::path out = s.dir / "out";
  {
    OutputDir o(out, "test");
    EXPECT_EQ(o.target(), out);
    EXPECT_NE(o.path(), out);
    EXPECT_EQ(o.path().parent_path(), s.dir);  // beside the target: the rename stays on one file system
    EXPECT_FALSE(fs::exists(out));             // nothing there until the commit
    vmsim::core::write_file_atomic(o.path() / "a.txt", "new");
    o.commit();
  }
  EXPECT_EQ(slurp(out / "a.txt"), "new");
  EXPECT_TRUE(fs::exists(out / vmsim::core::kOutputMarker));
  // Beside the target: the target and its lock file only.
  EXPECT_EQ(names(s.dir), (std::set<std::string>{"out", ".out.vmsim-lock"}));
}

TEST(OutputDir, ARerunReplacesThePreviousResultWhole) {
  Scratch s;
  const fs::path out = s.dir / "out";
  {
    OutputDir o(out, "first");
    put(o.path() / "deviation.csv", "old");
    put(o.path() / "report.json", "{}");
    o.commit();
  }
  {
    OutputDir o(out, "second");
    // Until the commit the previous result is whole.
    EXPECT_EQ(slurp(out / "deviation.csv"), "old");
    put(o.path() / "report.json", "{\"new\": 1}");
    o.commit();
  }
  EXPECT_EQ(names(out), (std::set<std::string>{"report.json", vmsim::core::kOutputMarker}));
  EXPECT_EQ(slurp(out / "report.json"), "{\"new\": 1}");
  EXPECT_EQ(names(s.dir), (std::set<std::string>{"out", ".out.vmsim-lock"}));
}

TEST(OutputDir, WithoutCommitThePreviousResultStays) {
  Scratch s;
  const fs::path out = s.dir / "out";
  {
    OutputDir o(out, "first");
    put(o.path() / "surface.csv", "old");
    o.commit();
  }
  try {
    OutputDir o(out, "second");
    put(o.path() / "surface.csv", "half");
    throw std::runtime_error("the run failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(slurp(out / "surface.csv"), "old");
  EXPECT_EQ(names(s.dir), (std::set<std::string>{"out", ".out.vmsim-lock"}));  // the staging directory went
}

TEST(OutputDir, ASecondWriterIsRefusedNamingTheDirectoryAndTheHolder) {
  Scratch s;
  const fs::path out = s.dir / "out";
  OutputDir first(out, "vmsim run");
  const std::string msg = output_dir_error_of([&] { OutputDir second(out, "vmsim run"); });
  EXPECT_NE(msg.find(out.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("another process is writing"), std::string::npos) << msg;
  EXPECT_NE(msg.find("pid " + std::to_string(::getpid())), std::string::npos) << msg;
  // The same path spelled otherwise is the same directory.
  EXPECT_NE(output_dir_error_of([&] { OutputDir third(s.dir / "." / "out/", "vmsim run"); }), "");
  // Once the first is gone, the directory is free again.
  first.commit();
}

TEST(OutputDir, StagingDirectoriesOfDeadProcessesAreRemoved) {
  Scratch s;
  const fs::path out = s.dir / "out";
  // What a killed run leaves: its staging directory with a half-written file, and a temporary file.
  const fs::path dead = s.dir / ".out.vmsim-staging-999999-deadbeef";
  fs::create_directories(dead / "images");
  put(dead / "surface.csv.tmp999999.1", "half");
  // Another directory's staging is not this run's to remove.
  const fs::path other = s.dir / ".other.vmsim-staging-999999-deadbeef";
  fs::create_directories(other);
  {
    OutputDir o(out, "test");
    EXPECT_FALSE(fs::exists(dead));
    o.commit();
  }
  EXPECT_TRUE(fs::exists(other));
}

// SIGTERM while threads are still writing into the staging directory (what `vmsim run` does when killed while it
// writes its outputs: files appear while the cleanup thread removes them). The process exits with 128 + SIGTERM,
// leaves no staging directory behind, and the previous result stays. Ten signals, at 0-9 ms of the writing.
TEST(OutputDir, SigtermWhileOtherThreadsWriteLeavesNoStaging) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  SignalScratch s("writers");
  const fs::path out = s.dir / "out";
  if (!s.child) {
    OutputDir o(out, "test");
    put(o.path() / "report.json", "previous");
    o.commit();
  }
  for (int k = 0; k < 10; ++k) {
    EXPECT_EXIT(
        {
          OutputDir o(out, "test");
          auto writer = [&o](int w) {
            for (long i = 0;; ++i) {  // as fast as files can be made, each call failing or not once the cleanup runs
              try {
                vmsim::core::create_result_subdir(o.path() / "images");
              } catch (const Error&) {
              }
              std::ofstream(o.path() / fmt_name(w, i)) << "data";
              std::ofstream(o.path() / "images" / fmt_name(w, i)) << "data";
            }
          };
          std::thread(writer, 0).detach();
          std::thread(writer, 1).detach();
          std::this_thread::sleep_for(std::chrono::milliseconds(k));
          ::kill(::getpid(), SIGTERM);
          std::this_thread::sleep_for(std::chrono::seconds(10));
          std::exit(0);  // the signal's exit never came
        },
        ::testing::ExitedWithCode(128 + SIGTERM), "")
        << "signal " << k;
    if (s.child) continue;
    EXPECT_EQ(s.staging_left(), "") << "signal " << k;
    EXPECT_EQ(slurp(out / "report.json"), "previous");
  }
}

// SIGTERM while staging directories are being made: runs into OUT one after another (each makes its staging
// directory, writes a file and gives up without commit), the signal at 0-2.7 ms. None may be left, whichever step the
// signal meets: the cleanup thread and the making of a staging directory exclude each other.
TEST(OutputDir, SigtermWhileAStagingDirectoryIsMadeLeavesNone) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  SignalScratch s("making");
  const fs::path out = s.dir / "out";
  for (int k = 0; k < 10; ++k) {
    EXPECT_EXIT(
        {
          { OutputDir first(out, "test"); }  // the handler is installed with the first one
          std::thread([k] {
            std::this_thread::sleep_for(std::chrono::microseconds(300 * k));
            ::kill(::getpid(), SIGTERM);
          }).detach();
          const auto t0 = std::chrono::steady_clock::now();
          while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10)) {
            try {
              OutputDir o(out, "test");
              put(o.path() / "report.json", "new");
            } catch (const Error&) {
            }
          }
          std::exit(0);  // the signal's exit never came
        },
        ::testing::ExitedWithCode(128 + SIGTERM), "")
        << "signal " << k;
    if (!s.child) {
      EXPECT_EQ(s.staging_left(), "") << "signal " << k;
    }
  }
}

// SIGTERM while commit() removes the previous result (after the swap, the staging name holds it): the cleanup
// thread and commit() remove the same tree at once. The process exits with 128 + SIGTERM, the new result is in
// place and nothing is left. The previous result has 300 files (a few ms to remove); the signal comes 0-9 ms
// into commit().
TEST(OutputDir, SigtermWhileTheCommitRemovesThePreviousResultLeavesNoStaging) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  SignalScratch s("commit");
  const fs::path out = s.dir / "out";
  for (int k = 0; k < 10; ++k) {
    if (!s.child) {
      OutputDir o(out, "test");
      for (int i = 0; i < 300; ++i) put(o.path() / ("f" + std::to_string(i)), "previous");
      put(o.path() / "report.json", "previous");
      o.commit();
    }
    EXPECT_EXIT(
        {
          OutputDir o(out, "test");
          put(o.path() / "report.json", "new");
          std::thread([k] {
            std::this_thread::sleep_for(std::chrono::milliseconds(k));
            ::kill(::getpid(), SIGTERM);
          }).detach();
          try {
            o.commit();
          } catch (const Error&) {
          }
          std::this_thread::sleep_for(std::chrono::seconds(10));
          std::exit(0);  // the signal's exit never came
        },
        ::testing::ExitedWithCode(128 + SIGTERM), "")
        << "signal " << k;
    if (s.child) continue;
    EXPECT_EQ(s.staging_left(), "") << "signal " << k;
    const std::string report = slurp(out / "report.json");
    EXPECT_TRUE(report == "new" || report == "previous") << report;
  }
}

TEST(OutputDir, RefusesDirectoriesItWouldDestroy) {
  Scratch s;
  // A directory of the user's (no report.json, no marker): replacing it would delete their files.
  fs::create_directories(s.dir / "mine");
  put(s.dir / "mine" / "job.toml", "x");
  std::string msg = output_dir_error_of([&] { OutputDir o(s.dir / "mine", "test"); });
  EXPECT_NE(msg.find("vmsim did not write"), std::string::npos) << msg;
  EXPECT_NE(msg.find("job.toml"), std::string::npos) << msg;
  EXPECT_EQ(slurp(s.dir / "mine" / "job.toml"), "x");
  // A file.
  put(s.dir / "file", "x");
  msg = output_dir_error_of([&] { OutputDir o(s.dir / "file", "test"); });
  EXPECT_NE(msg.find("not a directory"), std::string::npos) << msg;
  // The current directory (the default --out), or one holding it.
  const fs::path cwd = fs::current_path();
  fs::create_directories(s.dir / "here" / "deeper");
  fs::current_path(s.dir / "here" / "deeper");
  msg = output_dir_error_of([&] { OutputDir o(".", "test"); });
  const std::string msg_up = output_dir_error_of([&] { OutputDir o(s.dir / "here", "test"); });
  fs::current_path(cwd);
  EXPECT_NE(msg.find("current directory"), std::string::npos) << msg;
  EXPECT_NE(msg_up.find("current directory"), std::string::npos) << msg_up;
  // An empty directory and an earlier result of an older vmsim (report.json, no marker) are replaced.
  fs::create_directories(s.dir / "empty");
  EXPECT_EQ(output_dir_error_of([&] { OutputDir(s.dir / "empty", "test").commit(); }), "");
  fs::create_directories(s.dir / "older");
  put(s.dir / "older" / "report.json", "{}");
  put(s.dir / "older" / "deviation.csv", "stale");
  EXPECT_EQ(output_dir_error_of([&] { OutputDir(s.dir / "older", "test").commit(); }), "");
  EXPECT_FALSE(fs::exists(s.dir / "older" / "deviation.csv"));
}

TEST(OutputDir, RefusesAPathThatIsNotUtf8) {
  Scratch s;
  const std::string msg = output_dir_error_of([&] { OutputDir o(s.dir / "out\xff", "test"); });
  EXPECT_NE(msg.find("not valid UTF-8"), std::string::npos) << msg;
  EXPECT_NE(msg.find("out\\xff"), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(s.dir / "out\xff"));
}

// RFC 3629's table: what is and is not UTF-8.
TEST(Utf8, ValidAndInvalidSequences) {
  using vmsim::core::is_valid_utf8;
  EXPECT_TRUE(is_valid_utf8("plain/ascii path"));
  EXPECT_TRUE(is_valid_utf8("\xc3\xa9tude/\xe2\x82\xac/\xf0\x9f\x98\x80"));  // é, €, an emoji
  EXPECT_FALSE(is_valid_utf8("\xff"));
  EXPECT_FALSE(is_valid_utf8("caf\xe9"));           // Latin-1 é
  EXPECT_FALSE(is_valid_utf8("\xc3"));              // truncated
  EXPECT_FALSE(is_valid_utf8("\xe2\x82"));          // truncated
  EXPECT_FALSE(is_valid_utf8("\xc0\xaf"));          // overlong '/'
  EXPECT_FALSE(is_valid_utf8("\xed\xa0\x80"));      // a surrogate
  EXPECT_FALSE(is_valid_utf8("\xf4\x90\x80\x80"));  // beyond U+10FFFF
}

// A symlink planted where the temporary file would go (the names the earlier, predictable scheme used: target +
// ".tmp<pid>.<n>") is never followed: the victim it points to keeps its content.
TEST(AtomicFile, APlantedSymlinkIsNotFollowed) {
  Scratch s;
  const fs::path victim = s.dir / "victim.txt";
  put(victim, "precious");
  const fs::path target = s.dir / "report.json";
  for (int n = 0; n < 200; ++n) {
    fs::path planted = target;
    planted += ".tmp" + std::to_string(::getpid()) + "." + std::to_string(n);
    fs::create_symlink(victim, planted);
  }
  vmsim::core::write_file_atomic(target, "{\"ok\": true}");
  EXPECT_EQ(slurp(victim), "precious");
  EXPECT_EQ(slurp(target), "{\"ok\": true}");
  EXPECT_FALSE(fs::is_symlink(target));
}

// The temporary file is a new file of its own: created exclusively, gone after commit or on an error.
TEST(AtomicFile, TemporaryFileIsExclusiveAndCleanedUp) {
  Scratch s;
  const fs::path target = s.dir / "a.csv";
  {
    AtomicFile f(target);
    EXPECT_TRUE(fs::exists(f.temp_path()));
    EXPECT_FALSE(fs::is_symlink(f.temp_path()));
    f.stream() << "partial";
  }  // no commit
  EXPECT_TRUE(names(s.dir).empty());
  {
    AtomicFile f(target);
    f.stream() << "whole";
    f.commit();
  }
  EXPECT_EQ(names(s.dir), std::set<std::string>{"a.csv"});
  EXPECT_EQ(slurp(target), "whole");
}
