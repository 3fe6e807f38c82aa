#pragma once
// Slurm, driven from the outside: batch scripts a person can read and edit, sbatch to submit
// them, sacct and squeue to learn what became of the tasks. Nothing of Slurm is linked; its
// commands run as child processes. A bench folder's Slurm files are in DIR/slurm/:
// runs-<n>.sbatch and collect-<n>.sbatch (submission n), task-<job>_<i>.out (each task's
// output), collect-<job>.out, and jobs.tsv (one line per submission).

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/app/bench.hpp"

namespace mcslam::app::bench {

/// The full path of `name` in the folders of `path_variable` (PATH's form), or "".
std::string find_program(const std::string& name, const std::string& path_variable);

/// Where Slurm's commands are; a field is empty when the command is not on PATH.
struct SlurmTools {
  std::string sbatch, sacct, squeue;
  static SlurmTools from_path(const std::string& path_variable);
};

/// "0-7", "1,3-5": the task ids, ascending (they may come in any order).
std::string task_list(std::vector<int> tasks);
/// Parses a task list as above (also Slurm's "[1,3-5%2]"); nullopt for anything else.
std::optional<std::vector<int>> parse_task_list(std::string text);

/// One submission: a line of DIR/slurm/jobs.tsv.
struct Submission {
  int number = 1;
  std::string array_job, collect_job;
  std::vector<int> tasks;  ///< plan lines (from 0)
  std::string submitted_utc;
};

/// The submissions of a bench folder, oldest first (none when it was never submitted); broken
/// lines are an InputError naming the file and line.
std::vector<Submission> read_submissions(const std::string& dir);

/// Forgets the submissions of an earlier plan in the folder (removes jobs.tsv), so that a new
/// plan's runs are not taken for tasks of those jobs.
void forget_submissions(const std::string& dir);

/// The job id in `sbatch --parsable` output ("17" or "17;cluster", maybe after warnings).
std::optional<std::string> parse_job_id(const std::string& sbatch_output);

/// What one submission's scripts need.
struct ScriptInput {
  std::string dir;         ///< the bench folder (absolute)
  std::string executable;  ///< mcslam (absolute)
  SlurmOptions options;
  int number = 1;
  std::vector<int> tasks;
  std::string array_job;  ///< the collect script's dependency
};

/// The array's batch script: each task runs `mcslam bench --run-task DIR $SLURM_ARRAY_TASK_ID`.
std::string runs_script(const ScriptInput& in);
/// The collect job's batch script, to start after the array (afterany).
std::string collect_script(const ScriptInput& in);

/// The problem with `dir` as a bench folder for Slurm, nullopt when it can be one: an absolute
/// path (the nodes use it) without white space, quotes, backslashes, '$', '`' or '%' (it goes
/// into #SBATCH lines and the job scripts, where Slurm expands %x, %u, ... in --output).
std::optional<std::string> check_slurm_folder(const std::string& dir);

/// An exclusive lock on a bench folder (DIR/slurm/.lock, flock) for as long as it lives, so that
/// two bench commands never submit into one folder at once (jobs.tsv, the script numbers, the
/// check of what still runs). Waits up to `wait_s` for another holder, then InputError.
class BenchFolderLock {
 public:
  explicit BenchFolderLock(const std::string& dir, double wait_s = 30.0);
  ~BenchFolderLock();
  BenchFolderLock(const BenchFolderLock&) = delete;
  BenchFolderLock& operator=(const BenchFolderLock&) = delete;

 private:
  int fd_ = -1;
};

/// Checks `dir` (check_slurm_folder), writes the scripts, submits the array, then the collect job,
/// and appends the submission to jobs.tsv. InputError quoting sbatch when it rejects a script
/// (nothing is then submitted, or, when only the collect job is rejected, the array stays submitted
/// and the message says how to collect by hand).
Submission submit(const std::string& dir, const std::string& executable, const SlurmTools& tools,
                  const SlurmOptions& options, const std::vector<int>& tasks);

/// What Slurm says of one task: a state as sacct names it (TIMEOUT, FAILED, PENDING, ...), the
/// job step ("17_3") and where the state came from (sacct, squeue, or the task's output).
struct TaskState {
  std::string state;
  std::string job;
  std::string source;
};

/// States by task id from `sacct --noheader --parsable2 --format=JobID,State` output for one
/// array job; job steps are skipped, pending ranges ("17_[4-7%2]") expanded.
std::map<int, std::string> parse_sacct(const std::string& output, const std::string& array_job);
/// States by task id from `squeue --noheader --array --format=%i|%T` output for one array job.
std::map<int, std::string> parse_squeue(const std::string& output, const std::string& array_job);
/// The state a task's Slurm output shows when slurmstepd ended it (TIMEOUT for "DUE TO TIME
/// LIMIT", CANCELLED, PREEMPTED, NODE_FAIL, OUT_OF_MEMORY), nullopt when it shows none.
std::optional<std::string> state_in_output(const std::string& text);

/// DIR/slurm/task-<job>_<task>.out
std::string task_output_path(const std::string& dir, const std::string& array_job, int task);

/// The Slurm states of `tasks` (plan lines), each from the latest submission that holds it:
/// from sacct when it answers, else squeue for the tasks still queued or running, else the
/// task's output. `sacct_note` says why sacct was not used.
struct TaskStates {
  std::map<int, TaskState> by_task;
  std::string sacct_note;
};
TaskStates query_states(const std::string& dir, const std::vector<Submission>& submissions,
                        const std::vector<int>& tasks, const SlurmTools& tools);

/// True for states of a task that has not ended (PENDING, RUNNING, ...).
bool still_active(const std::string& state);

}  // namespace mcslam::app::bench
