#pragma once
// `mcslam bench`: every TUM-layout sequence under the data roots, run N times per ablation
// configuration in sequential mode (accuracy) and threaded mode (speed), each run in its own
// process so that one failure is reported and the rest go on; tables in Markdown, CSV and JSON,
// and a self-contained report.html. The runs are planned as data (DIR/plan.tsv and
// DIR/bench.json) and executed by a local process pool or a Slurm job array; the tables are
// made from the run folders alone (`--collect`).

#include <optional>
#include <string>
#include <vector>

namespace mcslam::app {

enum class BenchExecutor {
  kLocal,  ///< this machine, `jobs` runs at once
  kSlurm,  ///< one Slurm job array, one task per run, and a dependent collect job
};

/// How `mcslam bench --executor slurm` (and `--resubmit-failed`) submits its job array.
struct SlurmOptions {
  std::string partition;                 ///< empty: the cluster's default partition
  int time_limit_min = 0;                ///< per task (sbatch --time); 0: the partition's default
  int array_limit = 0;                   ///< tasks running at once (--array=...%K); 0: no limit
  std::vector<std::string> sbatch_args;  ///< extra sbatch options, one #SBATCH line each

  /// Why the options cannot be used (a negative limit, an argument that is not an option or
  /// holds a line break), or nullopt.
  std::optional<std::string> check() const;
};

struct BenchRequest {
  std::vector<std::string> data_roots;
  std::string output_dir;
  int runs = 3;  ///< per configuration and mode
  std::vector<std::string>
      configs;                     ///< subset of points,lines,planes,detection,full; all when empty
  std::vector<std::string> modes;  ///< sequential, threaded; both when empty
  std::vector<std::string> sequences;  ///< keep sequences whose name contains one of these
  std::optional<std::string> model;    ///< detector for sequences without their own detections.json
  std::optional<double> confidence;
  int max_frames = 0;       ///< per run; 0: all
  double timeout_s = 3600;  ///< per run; <= 0: none
  int overlays = 6;         ///< annotated frames per sequence in the report
  bool list_only = false;   ///< print the sequences found and stop
  bool progress = true;     ///< one line per run on stderr
  std::string executable;   ///< mcslam binary for the runs; this process's own when empty
  /// Folder holding report.js (the bundled page scripts); beside the executable when empty.
  std::string report_assets;
  std::string command_line;  ///< as typed, for the tables
  BenchExecutor executor = BenchExecutor::kLocal;
  int jobs = 1;  ///< local executor: runs at once (their speed figures then say so)
  SlurmOptions slurm;

  /// Why the request cannot be run, for what can be told without the file system (counts,
  /// ranges, options of the other executor, a relative output folder for Slurm), or nullopt.
  std::optional<std::string> check() const;
};

struct BenchOutcome {
  int runs = 0;
  int failed = 0;             ///< runs that failed
  int sequences_not_run = 0;  ///< sequences that cannot be read
  std::string markdown;       ///< the tables (also in results.md)
  std::string report_path;    ///< empty when the report could not be written
  std::string report_warning;
};

/// Validates the request (InputError: a missing root, no sequence found, runs < 1, an unknown
/// configuration or mode, a missing --model file, an output folder that cannot be made), writes
/// the plan, then runs everything on this machine. Failed runs do not throw: they are counted
/// and reported.
BenchOutcome run_bench(const BenchRequest& request);

struct SubmitOutcome {
  int tasks = 0;            ///< array tasks submitted
  std::string array_job;    ///< Slurm job id of the array
  std::string collect_job;  ///< Slurm job id of the dependent `--collect`
  std::string message;      ///< what was submitted and how to follow it, for the user
};

/// `--executor slurm`: validates the request as run_bench does (and that the output folder is
/// absolute, and sbatch is on PATH), writes the plan and the batch scripts into the output
/// folder, and submits one job array and a collect job that runs after it (afterany).
/// InputError when sbatch is missing or rejects a submission (naming the script and quoting
/// sbatch).
SubmitOutcome submit_bench(const BenchRequest& request);

/// `--resubmit-failed DIR`: submits again the runs of DIR's plan that have no successful
/// result and are not queued or running, with `slurm` (fields left at their defaults take the
/// bench's own); an outcome with 0 tasks when there is nothing to resubmit.
SubmitOutcome resubmit_failed(const std::string& dir, const SlurmOptions& slurm);

/// `--collect DIR`: scores every run of DIR's plan from its folder and writes the same tables
/// and report as a local bench; runs without a result are failed runs, with their Slurm state
/// when they were submitted to Slurm. InputError for a missing or broken plan.
BenchOutcome collect_bench(const std::string& dir, bool progress,
                           const std::string& report_assets = "");

/// `--run-task DIR INDEX`: runs the run on line INDEX (0-based) of DIR/plan.tsv into its folder,
/// as a Slurm array task does; returns the process exit code (0 when the run succeeded).
int run_bench_task(const std::string& dir, int index);

/// The sequences a bench would run, one per line (name, dataset, boxes, path).
std::string list_sequences(const BenchRequest& request);

}  // namespace mcslam::app
