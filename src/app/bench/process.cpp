#include "mcslam/app/bench/process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

extern char** environ;

namespace mcslam::app::bench {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Waits for the child until `deadline_s` after `start` (forever when <= 0); true when it ended.
bool wait_until(pid_t pid, int& status, Clock::time_point start, double deadline_s) {
  for (;;) {
    const pid_t r = waitpid(pid, &status, deadline_s > 0 ? WNOHANG : 0);
    if (r == pid) return true;
    if (r < 0 && errno != EINTR) return true;  // no such child any more
    if (deadline_s > 0 && seconds_since(start) >= deadline_s) return false;
    if (deadline_s > 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

}  // namespace

ProcessResult run_process(const std::string& executable, const std::vector<std::string>& args,
                          const std::string& log_path, double timeout_s) {
  ProcessResult result;
  std::vector<std::string> argv_storage;
  argv_storage.reserve(args.size() + 1);
  argv_storage.push_back(executable);
  argv_storage.insert(argv_storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_storage) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(),
                                   O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  const auto start = Clock::now();
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, executable.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    std::ofstream(log_path, std::ios::app)
        << "mcslam: error: cannot start " << executable << ": " << std::strerror(rc) << "\n";
    return result;
  }
  result.started = true;
  int status = 0;
  if (!wait_until(pid, status, start, timeout_s)) {
    result.timed_out = true;
    kill(pid, SIGTERM);
    if (!wait_until(pid, status, Clock::now(), 5.0)) {
      kill(pid, SIGKILL);
      wait_until(pid, status, Clock::now(), 0.0);
    }
  }
  result.wall_s = seconds_since(start);
  if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) result.signal = WTERMSIG(status);
  return result;
}

CapturedProcess capture_process(const std::string& executable, const std::vector<std::string>& args,
                                double timeout_s) {
  std::string path =
      (std::filesystem::temp_directory_path() / "mcslam-bench-output-XXXXXX").string();
  const int fd = mkstemp(path.data());
  CapturedProcess captured;
  if (fd < 0) {
    captured.output = "cannot make a temporary file in " +
                      std::filesystem::temp_directory_path().string() + ": " + std::strerror(errno);
    return captured;
  }
  close(fd);
  captured.result = run_process(executable, args, path, timeout_s);
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  captured.output = s.str();
  std::error_code ec;
  std::filesystem::remove(path, ec);
  return captured;
}

std::string failure_text(const ProcessResult& result, const std::string& log_path,
                         double timeout_s) {
  std::ifstream log(log_path);
  std::string line, last, error;
  while (std::getline(log, line)) {
    // A progress bar rewrites its line with \r: keep the last segment.
    if (const auto cr = line.rfind('\r'); cr != std::string::npos) line = line.substr(cr + 1);
    line = trim(line);
    if (line.empty()) continue;
    last = line;
    if (line.rfind("mcslam: error:", 0) == 0 || line.rfind("mcslam: unexpected error:", 0) == 0)
      error = line;
  }
  std::ostringstream s;
  if (!result.started)
    s << "could not start";
  else if (result.timed_out)
    s << "timed out after " << timeout_s << " s";
  else if (result.signal != 0)
    s << "killed by signal " << result.signal << " (" << strsignal(result.signal) << ")";
  else
    s << "exit code " << result.exit_code;
  const std::string detail = error.empty() ? last : error;
  if (!detail.empty()) s << ": " << detail;
  return s.str();
}

std::string current_executable() {
  std::error_code ec;
  const auto path = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : path.string();
}

}  // namespace mcslam::app::bench
