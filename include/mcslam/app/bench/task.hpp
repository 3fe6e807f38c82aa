#pragma once
// One run of a bench's plan executed into its folder, whoever executes it (the local process
// pool or a Slurm array task), and the record it leaves beside the folder when it ends
// (runs/<sequence>/<config>/<mode>-<i>.task.json): exit status, wall time, host, Slurm job. A
// run without a record never ended: it is still queued or running, or it was killed.

#include <optional>
#include <string>

#include "mcslam/app/bench/plan_file.hpp"

namespace mcslam::app::bench {

struct TaskRecord {
  bool started = false;  ///< false when mcslam could not be started
  int exit_code = -1;
  int signal = 0;
  bool timed_out = false;  ///< stopped by the bench's --timeout
  double wall_s = 0;
  double start_unix = 0, end_unix = 0;  ///< seconds since 1970
  std::string host;
  int cpus = 0;           ///< of the host
  std::string slurm_job;  ///< "17_3" when run by a Slurm array task, else empty
  std::string error;      ///< why it failed, one line (failure_text), empty when it succeeded

  bool ok() const { return started && !timed_out && signal == 0 && exit_code == 0; }
};

/// DIR/runs/<sequence>/<config>/<mode>-<i> and the log and record beside it.
std::string run_directory(const std::string& dir, const PlannedRun& run);
std::string run_log(const std::string& dir, const PlannedRun& run);
std::string task_record_path(const std::string& dir, const PlannedRun& run);

/// Removes what an earlier attempt left (folder, log, record), runs `executable` with the run's
/// arguments, its output appended to the log and stopped after `timeout_s` (none when <= 0),
/// then writes the record. The run's own failures do not throw.
TaskRecord execute_run(const std::string& dir, const PlannedRun& run, const std::string& executable,
                       double timeout_s, const std::string& slurm_job);

/// The run's record; nullopt when it has none. A record that cannot be read gives a failed
/// record whose error says so.
std::optional<TaskRecord> read_task_record(const std::string& path);

/// The time now as "2026-11-27T10:00:00Z".
std::string utc_now();

/// This machine's name.
std::string host_name();

}  // namespace mcslam::app::bench
