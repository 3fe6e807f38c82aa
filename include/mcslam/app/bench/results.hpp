#pragma once
// The figures of `mcslam bench`: each run scored from its output folder, the runs of one
// (sequence, configuration) summarised, and the tables (Markdown, CSV, JSON) a person reads.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/app/bench/plan.hpp"
#include "mcslam/app/bench/published.hpp"
#include "mcslam/core/trajectory.hpp"
#include "mcslam/eval/metrics.hpp"

namespace mcslam::app::bench {

/// One `mcslam run`, scored.
struct RunRecord {
  std::string sequence;
  std::string config;
  Mode mode = Mode::kSequential;
  int index = 1;
  std::string output;  ///< run folder, relative to the bench folder
  bool ok = false;
  std::string error;  ///< why it failed, one line
  std::string note;   ///< why a finished run has no ATE (e.g. no pose tracked)
  double wall_s = 0;
  int frames = 0;
  std::optional<double> ate_rmse_m, rpe_trans_m, rpe_rot_deg;  ///< need ground truth
  /// ATE of the trajectory before its positions were smoothed (summary.json).
  std::optional<double> unsmoothed_ate_rmse_m;
  /// ATE of the poses tracking gave at the time (trajectory_online.txt; summary.json).
  std::optional<double> online_ate_rmse_m;
  std::optional<double> tracked_ratio, fps, tracking_ms, dynamics_ms;
  /// Place recognition: keyframes in the map, loops verified and accepted, median ms of loop
  /// detection per keyframe and of the relocalisation database query, relocalisations.
  std::optional<double> keyframes, loops_verified, loops_accepted, loop_detection_ms,
      relocalisations, relocalisation_query_ms;
  /// Real-time runs: share of the camera's frames processed, latency median (ms), and the
  /// detector's forward passes per second (any threaded run with a model).
  std::optional<double> processed_ratio, latency_ms, detector_rate_hz;
  /// Median ms of each tracking stage, in pipeline order (image_load first).
  std::vector<std::pair<std::string, double>> stages_ms;
};

/// Scores a finished run from its folder: summary.json and timings.csv for coverage, speed and
/// stage times; trajectory.txt against `groundtruth` (when given) with the eval code, whose
/// report is stored in `eval_out` when not null. A folder whose files are missing or broken
/// gives a record with ok = false and the reason.
RunRecord score_run(const RunSpec& spec, const std::string& relative_output,
                    const std::optional<Trajectory>& groundtruth,
                    eval::EvalReport* eval_out = nullptr);

/// Median, minimum and maximum of the runs that gave a figure.
struct Spread {
  double median = 0, min = 0, max = 0;
  int n = 0;
};
std::optional<Spread> spread(const std::vector<double>& values);

/// The runs of one configuration on one sequence.
struct ConfigResult {
  Config config;
  std::optional<std::string> skipped;  ///< why it was not run
  std::vector<RunRecord> runs;
  /// Accuracy from the sequential runs (all runs when there are none), speed from the threaded
  /// runs (likewise).
  std::optional<Spread> ate, ate_threaded, rpe_trans, rpe_rot_deg, tracked, fps, tracking_ms;
  std::optional<Spread> ate_unsmoothed;  ///< the accuracy runs' ATE before smoothing
  std::optional<Spread> ate_online;      ///< the accuracy runs' ATE of the online poses
  std::optional<double> dynamics_ms;     ///< mean per frame, speed runs
  /// Place recognition (all runs): medians of RunRecord's figures.
  std::optional<Spread> keyframes, loops_verified, loops_accepted, loop_detection_ms,
      relocalisations, relocalisation_query_ms;
  std::vector<std::pair<std::string, double>> stages_ms;  ///< median over the speed runs
  /// Real-time runs (`--realtime`), when there are any: ATE on the frames processed, share of
  /// frames processed, latency median, detector rate, frame rate and per-stage medians.
  std::optional<Spread> ate_realtime, processed, latency_ms, detector_rate_hz, fps_realtime;
  std::vector<std::pair<std::string, double>> stages_ms_realtime;
};

/// Fills the figures of `result` from its runs.
void summarise(ConfigResult& result);

struct SequenceResult {
  Sequence sequence;
  std::string boxes;  ///< BoxSource::describe()
  int frames = 0;
  std::optional<std::string> groundtruth_note;  ///< why there is no ATE, when there is none
  std::optional<std::string> error;             ///< the sequence cannot be read: nothing was run
  std::vector<ConfigResult> configs;
  std::vector<PublishedRow> published;
};

struct BenchMeta {
  std::string created_utc;
  std::string command;
  std::string hostname;
  int cpus = 0;
  int runs_per_mode = 0;
  std::vector<Mode> modes;
  double wall_time_s = 0;
  /// How the runs were executed when that changes what the figures mean ("2 runs at once on
  /// this machine", "Slurm job array 17"); empty for one run at a time on this machine.
  std::string executor;
};

/// Our figure for a published row: the last configuration that has one (the full system when
/// it ran); nullopt when none has. Like with like: other systems publish the poses of each
/// frame as tracked and refined, never smoothed over the run, so an ATE is that of
/// trajectory_unsmoothed.txt (trajectory.txt where no smoothing was applied).
std::optional<std::pair<std::string, double>> our_figure(const SequenceResult& sequence,
                                                         Metric metric);
/// The ATE of the online poses (what `process()` returned at the time) of the configuration
/// our_figure chose for an ATE row; nullopt for other rows or without it.
std::optional<double> our_online_figure(const SequenceResult& sequence, Metric metric);

/// The tables, as printed and saved in results.md.
std::string markdown(const BenchMeta& meta, const std::vector<SequenceResult>& sequences);

/// One row per run (header first).
std::string runs_csv(const std::vector<SequenceResult>& sequences);

/// Every run and every summary as JSON (results.json).
nlohmann::json results_json(const BenchMeta& meta, const std::vector<SequenceResult>& sequences);

nlohmann::json to_json(const std::optional<Spread>& s);
nlohmann::json to_json(const RunRecord& run);

}  // namespace mcslam::app::bench
