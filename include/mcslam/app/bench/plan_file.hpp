#pragma once
// The plan of a bench as files in its output folder, written before anything runs, so that
// whoever executes the runs (this machine, a Slurm job array, a person) and whoever scores them
// read the same thing:
//  - DIR/bench.json: the bench's settings (sequences, configurations, modes, runs, limits);
//  - DIR/plan.tsv: one line per run: sequence, configuration, mode, index, then the exact
//    `mcslam run` arguments, tab-separated, one argument per column.
// Both are plain text a person can read and edit; a broken edit is an InputError naming the
// file, the line and the problem.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/app/bench.hpp"
#include "mcslam/app/bench/plan.hpp"

namespace mcslam::app::bench {

/// Everything about a bench but its runs (DIR/bench.json).
struct BenchSettings {
  std::string command;  ///< as typed
  std::string created_utc;
  BenchExecutor executor = BenchExecutor::kLocal;
  int jobs = 1;  ///< local executor: runs at once
  int runs = 3;  ///< per configuration and mode
  std::vector<Mode> modes;
  std::vector<Config> configs;
  std::vector<Sequence> sequences;
  std::optional<std::string> model;
  std::optional<double> confidence;
  int max_frames = 0;
  double timeout_s = 3600;
  int overlays = 6;
  SlurmOptions slurm;
};

/// One line of DIR/plan.tsv.
struct PlannedRun {
  std::string sequence;
  std::string config;
  Mode mode = Mode::kSequential;
  int index = 1;
  std::vector<std::string> arguments;  ///< of `mcslam run`, without the executable

  /// Its folder relative to the bench folder: runs/<sequence>/<config>/<mode>-<index>.
  std::string folder() const;
  /// "sequence · config · mode index", for messages.
  std::string describe() const;
  /// The value of its --output argument ("" when it has none).
  std::string output() const;
};

inline constexpr const char* kSettingsFile = "bench.json";
inline constexpr const char* kPlanFile = "plan.tsv";

nlohmann::json settings_json(const BenchSettings& settings);
/// InputError naming `path` for text that is not a bench's settings.
BenchSettings parse_settings(const std::string& text, const std::string& path);

/// The plan file's text: comment lines, the header row, one line per run. InputError when a
/// field holds a tab or a line break (a path the format cannot hold).
std::string plan_tsv(const std::vector<PlannedRun>& runs);

/// Parses the plan and checks each line against `settings`: a known sequence, configuration
/// and mode, an index from 1 to settings.runs, `run` arguments whose --output ends in the run's
/// folder and whose mode flag is the line's mode, no run twice. InputError "path:line: problem".
std::vector<PlannedRun> parse_plan(const std::string& text, const std::string& path,
                                   const BenchSettings& settings);

struct PlanFiles {
  BenchSettings settings;
  std::vector<PlannedRun> runs;
};

/// Writes DIR/bench.json and DIR/plan.tsv, each atomically.
void write_plan_files(const std::string& dir, const PlanFiles& plan);

/// Reads and checks DIR/bench.json and DIR/plan.tsv; InputError naming a missing or broken file.
PlanFiles read_plan_files(const std::string& dir);

}  // namespace mcslam::app::bench
