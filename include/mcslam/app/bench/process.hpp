#pragma once
// One child process with its output in a log file and a time limit: how `mcslam bench` runs
// `mcslam run`, so that a run that fails, crashes or hangs is reported and the others go on.

#include <string>
#include <vector>

namespace mcslam::app::bench {

struct ProcessResult {
  bool started = false;    ///< false when the executable could not be started
  int exit_code = -1;      ///< when it exited
  int signal = 0;          ///< when a signal ended it
  bool timed_out = false;  ///< killed at the time limit
  double wall_s = 0;

  bool ok() const { return started && !timed_out && signal == 0 && exit_code == 0; }
};

/// Runs `executable args...` with stdin from /dev/null and stdout and stderr appended to
/// `log_path`; kills it (SIGTERM, then SIGKILL after 5 s) when it runs longer than `timeout_s`
/// (no limit when <= 0). Never throws for the child's failures.
ProcessResult run_process(const std::string& executable, const std::vector<std::string>& args,
                          const std::string& log_path, double timeout_s);

/// The output of a short command (stdout and stderr together), and how it ended.
struct CapturedProcess {
  ProcessResult result;
  std::string output;
};

/// run_process with the output captured (through a temporary file) instead of kept in a log:
/// how the bench calls sbatch, sacct and squeue.
CapturedProcess capture_process(const std::string& executable, const std::vector<std::string>& args,
                                double timeout_s);

/// Why a run failed, in one line: the child's own "mcslam: error: ..." line when the log has
/// one (else its last line), after "exit code N", "killed by signal N (name)" or "timed out".
std::string failure_text(const ProcessResult& result, const std::string& log_path,
                         double timeout_s);

/// The path of the running executable (/proc/self/exe), or an empty string.
std::string current_executable();

}  // namespace mcslam::app::bench
