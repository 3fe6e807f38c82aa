#pragma once
// The figures of a bench gathered run by run, in plan order, whoever executed the runs: each run
// scored from its folder (or recorded as failed, with the reason), then the tables (results.md,
// runs.csv, results.json) and report.html. The local executor fills it as its runs end;
// `mcslam bench --collect` fills it from the folders of a bench that ran elsewhere.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/app/bench/plan.hpp"
#include "mcslam/app/bench/plan_file.hpp"
#include "mcslam/app/bench/results.hpp"
#include "mcslam/core/trajectory.hpp"
#include "mcslam/eval/metrics.hpp"

namespace mcslam::app::bench {

class Scoreboard {
 public:
  /// Reads each sequence of `settings` (frames, ground truth, where its boxes come from): a
  /// sequence that cannot be read is reported as not run, a configuration that needs boxes the
  /// sequence has not as skipped.
  explicit Scoreboard(const BenchSettings& settings);

  /// Every run of the bench in order (sequence, configuration, mode, index), its `mcslam run`
  /// arguments writing into `dir`; the first run of each configuration saves its map, that of a
  /// sequence's last configuration its annotated frames.
  std::vector<PlannedRun> plan(const std::string& dir) const;

  /// Why `run` cannot be part of this bench (its sequence unreadable, its configuration
  /// skipped), or nullopt.
  std::optional<std::string> check(const PlannedRun& run) const;

  /// Adds the k-th run of the plan: scored from its folder in `dir` when `failure` is empty,
  /// else recorded as failed with that text. Returns its record.
  const RunRecord& add(std::size_t k, const PlannedRun& run, const std::string& dir,
                       const std::string& failure, double wall_s);

  int sequences_not_run() const;

  /// Writes results.md, runs.csv and results.json into `dir`; returns the Markdown.
  std::string write_tables(const std::string& dir, const BenchMeta& meta) const;

  /// Writes `dir`/report.html with the page's scripts `assets`/report.js; returns its path, or
  /// "" with `warning` saying why when the scripts were not built.
  std::string write_report(const std::string& dir, const BenchMeta& meta,
                           const std::string& markdown, const std::string& assets,
                           std::string& warning) const;

 private:
  /// The run whose trajectory (and map, overlays) the report shows for one configuration: the
  /// first successful one in plan order.
  struct Representative {
    std::size_t k = 0;
    std::string dir;
    std::string folder;
    Trajectory estimate;
    std::optional<eval::EvalReport> report;
  };
  struct SequenceState {
    SequenceResult result;  ///< without runs (they are in records_)
    BoxSource boxes;
    std::optional<Trajectory> groundtruth;
    double t0 = 1, t1 = 0;  ///< time span of the frames run (t0 > t1: unknown)
    std::vector<std::optional<Representative>> representatives;  ///< per configuration
  };
  struct Entry {
    std::size_t sequence = 0, config = 0;
    RunRecord record;
  };

  SequenceState prepare(const Sequence& sequence) const;
  std::pair<std::size_t, std::size_t> locate(const PlannedRun& run) const;
  void consider_representative(std::size_t k, const Entry& entry, const std::string& run_dir,
                               const eval::EvalReport& report);
  std::vector<SequenceResult> results() const;
  nlohmann::json report_data(const BenchMeta& meta, const std::string& markdown) const;
  nlohmann::json sequence_report(std::size_t si, const SequenceResult& result) const;

  BenchSettings settings_;
  std::vector<SequenceState> states_;
  std::map<std::size_t, Entry> records_;  ///< by plan line
};

}  // namespace mcslam::app::bench
