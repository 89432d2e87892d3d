// vmsim study STUDY --out DIR: a job's variations through vmsim run's pipeline, one by one, or spread over MPI ranks
// with dynamic load balancing (mpirun -np N vmsim study ...). Rank 0 reads the study, keeps the queue and the table;
// every rank (rank 0 too, on a second thread) runs variations. Variations go out one at a time to whichever rank
// asks, so a slow variation never holds up the rest; the table is in the study's order whoever ran what.
#include "app/commands.hpp"
#include "app/commands_study.hpp"
#include "app/mpi_session.hpp"
#include "app/report.hpp"
#include "sim/study.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/timing.hpp"
#include "render/report_html.hpp"

#include <fmt/format.h>
#include <mpi.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <sstream>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <iostream>
#include <mutex>
#include <optional>
#include <thread>

namespace vmsim::app {

namespace {

namespace fs = std::filesystem;
using core::Clock;

constexpr int kTagToCoordinator = 7101;  // worker -> rank 0: "ready", with the result of its last variation
constexpr int kTagToWorker = 7102;       // rank 0 -> worker: the next variation, or stop

using core::seconds_since;

using core::process_cpu_s;

// A variation runs in a child process, `vmsim run` itself (posix_spawn of /proc/self/exe): a crash of any kind in
// it (a segfault, an abort, std::terminate, memory exhausted) ends that process only and becomes the variation's row.
// Its stdout and stderr go to the variation's run.log; the launcher's variables (Open MPI, PMI, PMIx) are left out of
// its environment so that it runs as one process and never joins the study's MPI job.
struct ChildEnd {
  int exit_code = -1;  // when it exited
  int signal = 0;      // when a signal ended it
  double cpu_s = 0;    // its user + system CPU time
};

std::vector<std::string> child_environment() {
  std::vector<std::string> env;
  for (char** e = environ; *e; ++e) {
    const std::string v = *e;
    if (v.rfind("OMPI_", 0) == 0 || v.rfind("PMI_", 0) == 0 || v.rfind("PMIX_", 0) == 0 || v.rfind("PRTE_", 0) == 0)
      continue;
    env.push_back(v);
  }
  return env;
}

ChildEnd run_child(const std::vector<std::string>& args, const fs::path& log) {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw core::Error("cannot find the vmsim executable (/proc/self/exe): " + ec.message());
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  std::vector<std::string> argv_s = {exe.string()};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv, envp;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env = child_environment();
  for (std::string& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  pid_t pid = -1;
  const int rc = ::posix_spawn(&pid, exe.c_str(), &fa, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw core::Error(fmt::format("cannot start {}: {}", exe.string(), std::strerror(rc)));
  int status = 0;
  struct rusage ru {};
  while (::wait4(pid, &status, 0, &ru) < 0) {
    if (errno != EINTR) throw core::Error(std::string("waiting for vmsim run: ") + std::strerror(errno));
  }
  ChildEnd end;
  if (WIFEXITED(status)) end.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) end.signal = WTERMSIG(status);
  end.cpu_s = ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
  return end;
}

// The message of the run's error in its log ("vmsim: error: ..." to the end), or its last line.
std::string error_in_log(const fs::path& log) {
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  for (const char* prefix : {"vmsim: error: ", "vmsim: internal error: "}) {
    const auto k = text.rfind(prefix);
    if (k == std::string::npos) continue;
    std::string m = text.substr(k + (std::string(prefix).find("internal") != std::string::npos ? 7 : 14));
    while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
    return m;
  }
  while (!text.empty() && text.back() == '\n') text.pop_back();
  const auto nl = text.rfind('\n');
  return nl == std::string::npos ? text : text.substr(nl + 1);
}

// The run's files, written by the child into DIR/run (its own output directory), moved up into DIR beside the
// variation's job and machine files.
void move_run_files(const fs::path& dir) {
  const fs::path run = dir / "run";
  for (const auto& e : fs::directory_iterator(run)) {
    const std::string n = e.path().filename().string();
    if (n == core::kOutputMarker) continue;
    fs::rename(e.path(), dir / n);
  }
  fs::remove_all(run);
  std::error_code ec;
  fs::remove(dir / ".run.vmsim-lock", ec);
}

// One variation, as rank 0 hands it out: everything a rank needs, so workers never read the study file.
nlohmann::json make_task(const sim::Study& study, const sim::StudyVariation& v, const sim::PreparedVariation& p,
                         const fs::path& out, const std::string& keep) {
  nlohmann::json t = {{"index", v.index},
                      {"label", fmt::format("{}: variation {} ({})", study.file.string(), v.index, v.name)},
                      {"dir", fs::absolute(sim::variation_dir(out, study, v)).string()},
                      {"job_toml", p.job_toml},
                      {"feed_scale", p.feed_scale},
                      {"keep", keep}};
  if (p.machine_toml) t["machine_toml"] = *p.machine_toml;
  nlohmann::json ov = nlohmann::json::array();
  for (const sim::StudyOverride& o : v.overrides) ov.push_back({{"key", o.key}, {"where", o.where}});
  t["overrides"] = ov;
  return t;
}

// A run's error names the variation's generated job or machine file; this adds where the study sets the key it
// names (the override whose last part the message quotes).
std::string with_study_key(const std::string& message, const nlohmann::json& task) {
  std::string out = message;
  if (!task.contains("overrides")) return out;
  for (const auto& o : task["overrides"]) {
    const std::string key = o.at("key").get<std::string>();
    const std::string last = key.substr(key.rfind('.') + 1);
    if (message.find("." + last + "'") != std::string::npos || message.find("'" + last + "'") != std::string::npos)
      out += fmt::format(" [{} sets {}]", o.at("where").get<std::string>(), key);
  }
  return out;
}

// Runs one variation in its own directory through vmsim run (no pictures); every error stays in its row.
sim::StudyResult run_variation(const nlohmann::json& task, int rank) {
  sim::StudyResult r;
  r.rank = rank;
  const auto t0 = Clock::now();
  const std::string label = task.at("label").get<std::string>();
  try {
    const fs::path dir = task.at("dir").get<std::string>();
    std::error_code ec;
    fs::remove_all(dir, ec);  // a previous study's files in this variation's directory would pass for its own
    core::create_result_subdir(dir.parent_path());  // variations/ (every rank's first variation tries)
    core::create_result_subdir(dir);
    core::write_file_atomic(dir / "job.toml", task.at("job_toml").get<std::string>());
    if (task.contains("machine_toml"))
      core::write_file_atomic(dir / "machine.toml", task["machine_toml"].get<std::string>());
    std::vector<std::string> args = {
        "run", (dir / "job.toml").string(), "--out", (dir / "run").string(), "--quiet", "--no-render"};
    const double feed_scale = task.at("feed_scale").get<double>();
    if (feed_scale != 1.0) args.insert(args.end(), {"--feed-scale", fmt::format("{:.17g}", feed_scale)});
    const ChildEnd end = run_child(args, dir / "run.log");
    r.cpu_s = end.cpu_s;
    if (end.signal != 0)
      throw core::Error(fmt::format("vmsim run was killed by signal {} ({}: {}); its output is in {}", end.signal,
                                    sigabbrev_np(end.signal) ? std::string("SIG") + sigabbrev_np(end.signal) : "?",
                                    strsignal(end.signal), (dir / "run.log").string()));
    if (end.exit_code != 0) {
      const std::string message = error_in_log(dir / "run.log");
      if (end.exit_code == 2 && !message.empty()) throw core::Error(message);  // vmsim's own error: a user's message
      throw core::Error(fmt::format("vmsim run ended with exit code {}: {} (see {})", end.exit_code, message,
                                    (dir / "run.log").string()));
    }
    move_run_files(dir);
    std::ifstream in(dir / "report.json");
    if (!in) throw core::Error((dir / "report.json").string() + ": the run wrote no report");
    const nlohmann::json report = nlohmann::json::parse(in);
    r.figures = sim::figures_from_report(report);
    r.status = sim::StudyResult::Status::Ok;
    if (task.value("keep", std::string("all")) == "summary") {
      for (const auto& e : fs::directory_iterator(dir)) {
        const std::string n = e.path().filename().string();
        if (n != "job.toml" && n != "machine.toml" && n != "report.json" && n != "run.log")
          fs::remove_all(e.path(), ec);
      }
      render::write_report_html(dir, report);  // again: its links to the files just removed go
    }
  } catch (const core::Error& e) {
    r.status = sim::StudyResult::Status::Failed;
    r.error = with_study_key(label + ": " + e.what(), task);
  } catch (const std::exception& e) {
    r.status = sim::StudyResult::Status::Failed;
    r.error = label + ": internal error: " + e.what();
  } catch (...) {
    r.status = sim::StudyResult::Status::Failed;
    r.error = label + ": internal error";
  }
  r.wall_s = seconds_since(t0);
  return r;
}

void send_json(const nlohmann::json& j, int dest, int tag) {
  const std::string s = j.dump();
  MPI_Send(s.data(), static_cast<int>(s.size()), MPI_CHAR, dest, tag, MPI_COMM_WORLD);
}

nlohmann::json recv_json(int source, int tag) {
  MPI_Status st;
  MPI_Probe(source, tag, MPI_COMM_WORLD, &st);
  int n = 0;
  MPI_Get_count(&st, MPI_CHAR, &n);
  std::string s(static_cast<std::size_t>(n), '\0');
  MPI_Recv(s.data(), n, MPI_CHAR, st.MPI_SOURCE, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return nlohmann::json::parse(s);
}

// rank 0's answer to this worker's request, waited for under the watchdog (mpi_session.hpp watchdog_seconds): rank 0
// answers within milliseconds (its main thread only polls), so a longer wait means it stopped.
nlohmann::json recv_answer(int rank) {
  const double limit_s = watchdog_seconds();
  const auto t0 = Clock::now();
  while (true) {
    int flag = 0;
    MPI_Iprobe(0, kTagToWorker, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
    if (flag) return recv_json(0, kTagToWorker);
    if (seconds_since(t0) > limit_s)
      throw core::Error(
          fmt::format("rank {}: rank 0 did not answer within {:g} s at study: the next variation "
                      "(stopped, or a stalled file system?); the job is ended (the limit: "
                      "--watchdog-s, or VMSIM_WATCHDOG_S)",
                      rank, limit_s));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

// Variation i as a task for a rank; one whose overrides cannot be applied is `failed` (its row) instead.
std::optional<nlohmann::json> prepare_task(const sim::Study& study, std::size_t i, const StudyArgs& args,
                                           sim::StudyResult& failed) {
  try {
    return make_task(study, study.variations[i], sim::prepare_variation(study, study.variations[i]), args.out_dir,
                     args.keep);
  } catch (const std::exception& e) {  // core::Error names the study file, the variation and the key
    failed.status = sim::StudyResult::Status::Failed;
    failed.error = dynamic_cast<const core::Error*>(&e)
                       ? std::string(e.what())
                       : fmt::format("{}: variation {} ({}): {}", study.file.string(), study.variations[i].index,
                                     study.variations[i].name, e.what());
    return std::nullopt;
  }
}

// A worker's message to rank 0: its request for work, with the result of the variation it just ran.
struct Request {
  int rank = 0;
  std::size_t index = 0;  // 1-based; 0: no result (its first request)
  std::optional<sim::StudyResult> result;
};
std::optional<Request> poll_request(std::size_t n) {
  int flag = 0;
  MPI_Status st;
  MPI_Iprobe(MPI_ANY_SOURCE, kTagToCoordinator, MPI_COMM_WORLD, &flag, &st);
  if (!flag) return std::nullopt;
  Request r;
  r.rank = st.MPI_SOURCE;
  const nlohmann::json msg = recv_json(r.rank, kTagToCoordinator);
  if (msg.contains("index")) {
    r.index = msg["index"].get<std::size_t>();
    if (r.index < 1 || r.index > n)
      throw core::Error(fmt::format("rank {} sent a result for variation {}", r.rank, r.index));
    r.result = sim::result_from_json(msg["result"]);
  }
  return r;
}

// The progress line of a finished variation.
std::string finished_line(std::size_t shown, std::size_t n, const sim::StudyVariation& v, const sim::StudyResult& r) {
  if (r.status != sim::StudyResult::Status::Ok)
    return fmt::format("[{}/{}] variation {} ({}): FAILED: {}", shown, n, v.index, v.name, r.error);
  const sim::StudyFigures& f = r.figures;
  return fmt::format(
      "[{}/{}] variation {} ({}): ok, deepest mark {}, contour error max {}, {:.1f} s CPU on rank {}", shown, n,
      v.index, v.name, f.mark_depth_mm ? fmt::format("{:.2f} um", *f.mark_depth_mm * 1e3) : std::string("none"),
      f.contour_error_max_mm ? fmt::format("{:.2f} um", *f.contour_error_max_mm * 1e3) : std::string("-"), r.cpu_s,
      r.rank);
}

// Ranks 1..N-1: ask rank 0 for a variation, run it, send its result with the next request, until told to stop.
int worker_loop(int rank) {
  // Test hook (tests/app/study_cli_test.cpp, README "What you can rely on"): this rank stops (SIGSTOP) at once.
  if (const char* h = std::getenv("VMSIM_TEST_STOP_RANK"); h && std::atoi(h) == rank) std::raise(SIGSTOP);
  nlohmann::json msg = {{"rank", rank}};
  while (true) {
    send_json(msg, 0, kTagToCoordinator);
    const nlohmann::json task = recv_answer(rank);
    if (task.contains("stop")) return 0;
    const sim::StudyResult r = run_variation(task, rank);
    msg = {{"rank", rank}, {"index", task.at("index")}, {"result", sim::result_to_json(r)}};
  }
}

// The queue and the table of a study, shared by rank 0's two threads: the main thread (MPI, the only one that calls
// it: MPI_THREAD_FUNNELED) and the local worker. Each result is written once, before it is listed as finished.
class StudyTable {
 public:
  StudyTable(const sim::Study& study, const StudyArgs& staged) : study_(study), staged_(staged) {
    for (std::size_t i = 0; i < study.variations.size(); ++i) queue_.push_back(i);
    results_.resize(study.variations.size());
  }
  void store(std::size_t i, const sim::StudyResult& r) {
    std::lock_guard<std::mutex> lock(mu_);
    results_[i] = r;
    finished_.push_back(i);
  }
  // The next variation ready to run; one whose overrides cannot be applied is a failed row at once.
  std::optional<nlohmann::json> next_task() {
    while (true) {
      std::size_t i;
      {
        std::lock_guard<std::mutex> lock(mu_);
        if (queue_.empty()) return std::nullopt;
        i = queue_.front();
        queue_.pop_front();
      }
      sim::StudyResult failed;
      if (auto task = prepare_task(study_, i, staged_, failed)) return task;
      store(i, failed);
    }
  }
  void clear_queue() {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.clear();
  }
  // The variations finished since the last call, in the order they finished.
  std::vector<std::size_t> take_finished() {
    std::lock_guard<std::mutex> lock(mu_);
    std::vector<std::size_t> fresh(finished_.begin() + static_cast<std::ptrdiff_t>(reported_), finished_.end());
    reported_ = finished_.size();
    return fresh;
  }
  std::size_t reported() const { return reported_; }                           // main thread only
  const sim::StudyResult& result(std::size_t i) const { return results_[i]; }  // i listed as finished
  std::vector<sim::StudyResult> snapshot() const {
    std::lock_guard<std::mutex> lock(mu_);
    return results_;
  }

 private:
  const sim::Study& study_;
  const StudyArgs& staged_;
  mutable std::mutex mu_;
  std::deque<std::size_t> queue_;
  std::vector<sim::StudyResult> results_;
  std::vector<std::size_t> finished_;
  std::size_t reported_ = 0;
};

void write_tables(const fs::path& dir, const sim::Study& study, const std::vector<sim::StudyResult>& results, int ranks,
                  double elapsed_s) {
  core::write_file_atomic(dir / "results.csv", sim::results_csv(study, results));
  const nlohmann::json sj = sim::study_json(study, results, ranks, elapsed_s);
  core::write_file_atomic(dir / "study.json", sj.dump(2) + "\n");
  render::write_report_html(dir, sj);
}

}  // namespace

int run_study(const StudyArgs& args) {
  if (args.keep != "all" && args.keep != "summary")
    throw core::Error("--keep: expected \"all\" or \"summary\", found \"" + args.keep + "\"");
  const int rank = mpi_rank(), size = mpi_active() ? mpi_size() : 1;
  if (rank != 0) return worker_loop(rank);

  const auto t_start = Clock::now();
  require_utf8_input(args.study, "the study file");
  const sim::Study study = sim::load_study(args.study);
  // The whole study is one result directory (core/output_dir.hpp): written in its staging directory (results.csv and
  // study.json there as rows finish), swapped into place at the end; the tasks name the staging paths.
  core::OutputDir out(args.out_dir, "vmsim study");
  StudyArgs staged = args;
  staged.out_dir = out.path();
  const std::size_t n = study.variations.size();
  StudyTable table(study, staged);

  // Progress lines go to the terminal through a copy of stdout taken now: the local worker points stdout at its
  // variation's run.log while it runs.
  FILE* console = fdopen(::dup(1), "w");
  if (console) std::setvbuf(console, nullptr, _IOLBF, 0);
  auto say = [&](const std::string& line) {
    if (console && !args.quiet) std::fputs((line + "\n").c_str(), console);
  };
  say(fmt::format("study {}: {} variations of {} on {} rank{}", study.name, n, study.base_job.string(), size,
                  size > 1 ? "s" : ""));

  std::atomic<bool> local_done{false};
  std::thread local([&] {
    while (auto task = table.next_task())
      table.store(task->at("index").get<std::size_t>() - 1, run_variation(*task, 0));
    local_done = true;
  });

  std::size_t written = 0;
  auto last_write = Clock::now();
  double write_s = 0;
  int remote_active = size - 1;
  // Every worker asks for its first variation as it starts: one that has not within the watchdog's limit is named.
  std::vector<char> heard(static_cast<std::size_t>(size), 0);
  const double watchdog_s = size > 1 ? watchdog_seconds() : 0.0;
  bool all_heard = size == 1;
  try {
    while (true) {
      bool busy = false;
      if (!all_heard && seconds_since(t_start) > watchdog_s) {
        std::string missing;
        for (int r = 1; r < size; ++r)
          if (!heard[static_cast<std::size_t>(r)]) missing += (missing.empty() ? "" : ", ") + std::to_string(r);
        if (!missing.empty())
          throw core::Error(
              fmt::format("rank 0: rank {} did not reach study: the first request for a variation "
                          "within {:g} s (stopped, or a stalled file system?); the job is ended (the "
                          "limit: --watchdog-s, or VMSIM_WATCHDOG_S)",
                          missing, watchdog_s));
        all_heard = true;
      }
      if (remote_active > 0) {
        // A worker's request (with the result of its last variation): its next variation, or stop.
        const std::optional<Request> req = poll_request(n);
        if (req) {
          busy = true;
          heard[static_cast<std::size_t>(req->rank)] = 1;
          if (req->result) table.store(req->index - 1, *req->result);
          if (auto task = table.next_task()) {
            send_json(*task, req->rank, kTagToWorker);
          } else {
            send_json({{"stop", true}}, req->rank, kTagToWorker);
            --remote_active;
          }
        }
      }
      std::size_t shown = table.reported();
      for (std::size_t i : table.take_finished()) say(finished_line(++shown, n, study.variations[i], table.result(i)));
      // The table so far, now and then: a study cut short (a killed job) keeps what it had. Every 2 s at most, and
      // never more than 5 % of the time (a study of many variations has long tables).
      if (table.reported() > written && seconds_since(last_write) > std::max(2.0, 20 * write_s)) {
        const auto w0 = Clock::now();
        write_tables(out.path(), study, table.snapshot(), size, seconds_since(t_start));
        write_s = seconds_since(w0);
        written = table.reported();
        last_write = Clock::now();
      }
      if (remote_active == 0 && local_done) break;
      if (!busy) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  } catch (...) {
    table.clear_queue();
    local.join();
    if (console) std::fclose(console);
    throw;
  }
  local.join();
  const std::vector<sim::StudyResult> results = table.snapshot();
  write_tables(out.path(), study, results, size, seconds_since(t_start));
  out.commit();
  int ok = 0;
  for (const sim::StudyResult& r : results) ok += r.status == sim::StudyResult::Status::Ok;
  say(fmt::format("study {}: {} ok, {} failed of {} variations on {} rank{} in {:.1f} s; wrote {} and {}", study.name,
                  ok, static_cast<int>(n) - ok, n, size, size > 1 ? "s" : "", seconds_since(t_start),
                  (args.out_dir / "results.csv").string(), (args.out_dir / "study.json").string()));
  if (console) std::fclose(console);
  return 0;
}

}  // namespace vmsim::app
