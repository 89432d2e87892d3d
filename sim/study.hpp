#pragma once
// Studies (vmsim study): a base job and its variations (explicit [[variation]] tables, or a [grid] whose cartesian
// product gives them), each a set of key overrides of the job file or of its machine file. This part is pure: it
// reads the study file, writes each variation's job (and machine) TOML, and turns run results into the table. The
// distribution over MPI ranks is app/cmd_study.cpp. The schema is documented in parts/README.md.
#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::sim {

// One override: a dotted key ("interpolation.tolerance_mm", "machine.axes.X.drive.kv_1000_per_min", "feed_scale")
// and its value as TOML text (what the variation's files get), with where the study file sets it.
struct StudyOverride {
  std::string key;
  std::string value_toml;  // the value as a TOML expression: 0.02, "file.csv", [1.0, 2.0, 3.0]
  std::string value_cell;  // as the results table shows it (strings without quotes)
  std::string where;       // "study.toml:12:1"
};

struct StudyVariation {
  int index = 0;                         // 1-based, in the study's order
  std::string name;                      // [[variation]] name, or "<index>"
  std::vector<StudyOverride> overrides;  // [common] first, then the variation's own (later ones win)
};

struct Study {
  std::filesystem::path file;  // the study file
  std::string name;
  std::filesystem::path base_job;  // [study] job, resolved against the study file's directory
  std::vector<StudyVariation> variations;
  std::vector<std::string> varied_keys;  // keys any variation sets itself (not [common]), in order of appearance
};

// Reads and checks a study file. Errors (core::Error) name the file, line and key.
Study load_study(const std::filesystem::path& path);

// What one variation runs: its files' text and the run's feed scale.
struct PreparedVariation {
  std::string job_toml;                     // the job file (every path in it absolute)
  std::optional<std::string> machine_toml;  // a changed machine file (the job then names "machine.toml" beside it)
  double feed_scale = 1.0;
};

// Applies a variation's overrides to the base job (and its machine file). Paths of the base job are made absolute
// (resolved against the base job's directory); paths a variation sets are resolved against the study file's
// directory. Errors (core::Error) name the study file, the variation and the key.
PreparedVariation prepare_variation(const Study& study, const StudyVariation& v);

// The figures of one variation, from its run's report.json (vmsim run).
struct StudyFigures {
  int marks = 0;
  std::optional<double> mark_depth_mm;   // the deepest mark
  std::optional<std::string> mark_kind;  // "overcut" | "undercut"
  std::optional<double> deviation_min_mm, deviation_max_mm;
  std::optional<double> contour_error_max_mm, contour_error_rms_mm;  // on cutting moves
  std::optional<double> cycle_time_s;
};
StudyFigures figures_from_report(const nlohmann::json& report);

// One row of the results table.
struct StudyResult {
  enum class Status { Pending, Ok, Failed } status = Status::Pending;
  std::string error;  // Failed: the message
  StudyFigures figures;
  double cpu_s = 0, wall_s = 0;
  int rank = -1;  // which rank ran it (study.json only: the table does not depend on it)
};

nlohmann::json result_to_json(const StudyResult& r);  // for the messages between ranks
StudyResult result_from_json(const nlohmann::json& j);

// DIR/results.csv: one row per variation in the study's order. Every column but cpu_time_s is independent of the
// ranks, threads and order the variations ran in.
std::string results_csv(const Study& study, const std::vector<StudyResult>& results);
// DIR/study.json: the study, its base job, each variation's overrides, figures, status, rank and times.
nlohmann::json study_json(const Study& study, const std::vector<StudyResult>& results, int ranks, double wall_s);

// The directory of variation `v` under the output directory: DIR/variations/NNN.
std::filesystem::path variation_dir(const std::filesystem::path& out_dir, const Study& study, const StudyVariation& v);

}  // namespace vmsim::sim
