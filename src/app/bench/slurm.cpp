#include "mcslam/app/bench/slurm.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include "mcslam/app/bench/process.hpp"
#include "mcslam/app/bench/task.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::app {

std::optional<std::string> SlurmOptions::check() const {
  if (time_limit_min < 0)
    return "--time-limit: must not be negative (minutes per task; 0: the partition's default)";
  if (array_limit < 0) return "--array-limit: must not be negative (0: no limit)";
  if (partition.find_first_of(" \t\n") != std::string::npos)
    return "--partition: '" + partition + "' holds a space or line break";
  for (const std::string& a : sbatch_args)
    if (a.size() < 2 || a[0] != '-' || a.find_first_of("\n\r") != std::string::npos)
      return "--sbatch-arg: '" + a +
             "' is not one sbatch option (give each as --sbatch-arg=--mem=4G; it becomes an "
             "#SBATCH line of the batch scripts)";
  return std::nullopt;
}

}  // namespace mcslam::app

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

constexpr double kCommandTimeoutS = 120;
constexpr const char* kJobsHeader = "submission\tarray_job\tcollect_job\ttasks\tsubmitted_utc";

std::string slurm_dir(const std::string& dir) { return (fs::path(dir) / "slurm").string(); }

std::string jobs_path(const std::string& dir) {
  return (fs::path(slurm_dir(dir)) / "jobs.tsv").string();
}

/// Single quotes for the shell.
std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

/// The non-empty lines of a command's output, trimmed, joined by "; ".
std::string one_line(const std::string& output) {
  std::istringstream in(output);
  std::string joined;
  for (std::string line; std::getline(in, line);)
    if (!trim(line).empty()) joined += (joined.empty() ? "" : "; ") + trim(line);
  return joined.empty() ? "no output" : joined;
}

/// The #SBATCH lines both scripts share: partition, time limit, the user's own options.
std::string common_directives(const SlurmOptions& o) {
  std::ostringstream s;
  if (!o.partition.empty()) s << "#SBATCH --partition=" << o.partition << "\n";
  if (o.time_limit_min > 0) s << "#SBATCH --time=" << o.time_limit_min << "\n";
  for (const std::string& a : o.sbatch_args) s << "#SBATCH " << a << "\n";
  return s.str();
}

std::string submission_line(const Submission& s) {
  return std::to_string(s.number) + "\t" + s.array_job + "\t" + s.collect_job + "\t" +
         task_list(s.tasks) + "\t" + s.submitted_utc + "\n";
}

Submission parse_submission(const std::string& line) {
  std::vector<std::string> f;
  std::istringstream in(line);
  for (std::string field; std::getline(in, field, '\t');) f.push_back(field);
  const auto tasks = f.size() == 5 ? parse_task_list(f[3]) : std::nullopt;
  if (!tasks || f[1].empty() || f[1].find_first_not_of("0123456789") != std::string::npos)
    throw InputError(
        "expected submission, array job id, collect job id, tasks (0-7 or 1,3) "
        "and time, tab-separated");
  Submission s;
  s.number = std::atoi(f[0].c_str());
  s.array_job = f[1];
  s.collect_job = f[2];
  s.tasks = *tasks;
  s.submitted_utc = f[4];
  return s;
}

/// Runs `sbatch --parsable script`; the job id, or InputError quoting sbatch.
std::string sbatch(const SlurmTools& tools, const std::string& script) {
  const CapturedProcess c = capture_process(tools.sbatch, {"--parsable", script}, kCommandTimeoutS);
  const auto id = c.result.ok() ? parse_job_id(c.output) : std::nullopt;
  if (!id)
    throw InputError("sbatch rejected " + script + ": " +
                     (c.result.ok() ? "no job id in its output: " : "") + one_line(c.output));
  return *id;
}

void append_submission(const std::string& dir, const Submission& s) {
  std::string text;
  std::ifstream in(jobs_path(dir), std::ios::binary);
  if (in) {
    std::ostringstream old;
    old << in.rdbuf();
    text = old.str();
  } else {
    text = "# mcslam bench submissions to Slurm, one per line (tab-separated)\n" +
           std::string(kJobsHeader) + "\n";
  }
  io::write_file_atomic(jobs_path(dir), text + submission_line(s));
}

/// The last submission that holds `task`, or null.
const Submission* latest_with(const std::vector<Submission>& submissions, int task) {
  for (auto it = submissions.rbegin(); it != submissions.rend(); ++it)
    if (std::find(it->tasks.begin(), it->tasks.end(), task) != it->tasks.end()) return &*it;
  return nullptr;
}

/// The first word of a state ("CANCELLED by 0" gives CANCELLED).
std::string state_word(const std::string& s) {
  const std::string t = trim(s);
  return t.substr(0, t.find(' '));
}

/// Task ids of a job id field "17_3" or "17_[4-7%2]" of `array_job`; empty for anything else.
std::vector<int> tasks_of(const std::string& job_field, const std::string& array_job) {
  const std::string prefix = array_job + "_";
  if (job_field.rfind(prefix, 0) != 0 || job_field.find('.') != std::string::npos) return {};
  const auto tasks = parse_task_list(job_field.substr(prefix.size()));
  return tasks ? *tasks : std::vector<int>{};
}

/// "a|b" lines of a command's output for one array job, as task -> state.
std::map<int, std::string> parse_pairs(const std::string& output, const std::string& array_job) {
  std::map<int, std::string> states;
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);) {
    const auto bar = line.find('|');
    if (bar == std::string::npos) continue;
    for (int task : tasks_of(trim(line.substr(0, bar)), array_job))
      states[task] = state_word(line.substr(bar + 1, line.find('|', bar + 1) - bar - 1));
  }
  return states;
}

/// sacct's states of each array job, or nullopt (with the reason) when sacct cannot answer.
std::optional<std::map<std::string, std::map<int, std::string>>> sacct_states(
    const std::vector<std::string>& jobs, const SlurmTools& tools, std::string& note) {
  if (tools.sacct.empty()) {
    note = "sacct is not on PATH";
    return std::nullopt;
  }
  std::map<std::string, std::map<int, std::string>> states;
  for (const std::string& job : jobs) {
    const CapturedProcess c = capture_process(
        tools.sacct, {"--noheader", "--parsable2", "--jobs=" + job, "--format=JobID,State"},
        kCommandTimeoutS);
    if (!c.result.ok()) {
      note = "sacct: " + one_line(c.output);
      return std::nullopt;
    }
    states[job] = parse_sacct(c.output, job);
  }
  return states;
}

std::map<int, std::string> squeue_states(const std::string& job, const SlurmTools& tools) {
  if (tools.squeue.empty()) return {};
  const CapturedProcess c = capture_process(
      tools.squeue, {"--noheader", "--array", "--jobs=" + job, "--format=%i|%T"}, kCommandTimeoutS);
  // squeue fails once a job has left the controller: nothing is queued or running then.
  return c.result.ok() ? parse_squeue(c.output, job) : std::map<int, std::string>{};
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

std::string find_program(const std::string& name, const std::string& path_variable) {
  std::istringstream in(path_variable);
  for (std::string folder; std::getline(in, folder, ':');) {
    const fs::path candidate = fs::path(folder.empty() ? "." : folder) / name;
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec) && access(candidate.c_str(), X_OK) == 0)
      return fs::absolute(candidate, ec).string();
  }
  return "";
}

SlurmTools SlurmTools::from_path(const std::string& path_variable) {
  return {find_program("sbatch", path_variable), find_program("sacct", path_variable),
          find_program("squeue", path_variable)};
}

std::string task_list(std::vector<int> tasks) {
  std::sort(tasks.begin(), tasks.end());
  tasks.erase(std::unique(tasks.begin(), tasks.end()), tasks.end());
  std::string text;
  for (std::size_t i = 0; i < tasks.size();) {
    std::size_t j = i;
    while (j + 1 < tasks.size() && tasks[j + 1] == tasks[j] + 1) ++j;
    // (append, not "-" + ...: GCC 12 misreports -Wrestrict on that concatenation)
    if (!text.empty()) text.append(",");
    text.append(std::to_string(tasks[i]));
    if (j > i) text.append("-").append(std::to_string(tasks[j]));
    i = j + 1;
  }
  return text;
}

std::optional<std::vector<int>> parse_task_list(std::string text) {
  if (text.size() >= 2 && text.front() == '[' && text.back() == ']')
    text = text.substr(1, text.size() - 2);
  text = text.substr(0, text.find('%'));
  std::vector<int> tasks;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    const auto dash = item.find('-');
    const std::string a = item.substr(0, dash);
    const std::string b = dash == std::string::npos ? a : item.substr(dash + 1);
    const auto digits = [](const std::string& s) {
      return !s.empty() && s.size() < 9 && s.find_first_not_of("0123456789") == std::string::npos;
    };
    if (!digits(a) || !digits(b) || std::stoi(b) < std::stoi(a)) return std::nullopt;
    for (int t = std::stoi(a); t <= std::stoi(b); ++t) tasks.push_back(t);
  }
  if (tasks.empty()) return std::nullopt;
  return tasks;
}

std::vector<Submission> read_submissions(const std::string& dir) {
  std::ifstream in(jobs_path(dir), std::ios::binary);
  std::vector<Submission> submissions;
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    if (line.empty() || line[0] == '#' || line.rfind("submission\t", 0) == 0) continue;
    try {
      submissions.push_back(parse_submission(line));
    } catch (const InputError& e) {
      throw InputError(jobs_path(dir) + ":" + std::to_string(number) + ": " + e.what());
    }
  }
  return submissions;
}

void forget_submissions(const std::string& dir) {
  std::error_code ec;
  fs::remove(jobs_path(dir), ec);
}

std::optional<std::string> parse_job_id(const std::string& sbatch_output) {
  std::optional<std::string> id;
  std::istringstream in(sbatch_output);
  for (std::string line; std::getline(in, line);) {
    const std::string digits = trim(line).substr(0, trim(line).find(';'));
    if (!digits.empty() && digits.find_first_not_of("0123456789") == std::string::npos) id = digits;
  }
  return id;
}

std::string runs_script(const ScriptInput& in) {
  const std::string n = std::to_string(in.number);
  std::ostringstream s;
  s << "#!/bin/bash\n"
       "# mcslam bench, submission "
    << n
    << ": one Slurm array task per run. Task i runs the i-th run of plan.tsv\n"
       "# (from 0) into runs/<sequence>/<config>/<mode>-<index>/ and leaves the run's log\n"
       "# (.log) and record (.task.json) beside that folder. Submitted by mcslam as\n"
       "#   sbatch --parsable "
    << slurm_dir(in.dir) << "/runs-" << n << ".sbatch\n"
    << "#SBATCH --job-name=mcslam-bench\n"
    << "#SBATCH --array=" << task_list(in.tasks)
    << (in.options.array_limit > 0 ? "%" + std::to_string(in.options.array_limit) : "") << "\n"
    << "#SBATCH --output=\"" << slurm_dir(in.dir) << "/task-%A_%a.out\"\n"
    << common_directives(in.options) << "exec " << shell_quote(in.executable)
    << " bench --run-task " << shell_quote(in.dir) << " \"$SLURM_ARRAY_TASK_ID\"\n";
  return s.str();
}

std::string collect_script(const ScriptInput& in) {
  std::ostringstream s;
  s << "#!/bin/bash\n"
       "# mcslam bench, submission "
    << in.number << ": once job array " << in.array_job
    << " has ended (in any way), score its runs\n"
       "# and write results.md, results.json, runs.csv and report.html into the bench folder.\n"
    << "#SBATCH --job-name=mcslam-bench-collect\n"
    << "#SBATCH --dependency=afterany:" << in.array_job << "\n"
    << "#SBATCH --output=\"" << slurm_dir(in.dir) << "/collect-%j.out\"\n"
    << common_directives(in.options) << "exec " << shell_quote(in.executable) << " bench --collect "
    << shell_quote(in.dir) << " --quiet\n";
  return s.str();
}

std::optional<std::string> check_slurm_folder(const std::string& dir) {
  if (!fs::path(dir).is_absolute())
    return dir +
           ": with --executor slurm the bench folder must be an absolute path, on a file "
           "system that the cluster's nodes share: the tasks write their runs into it from "
           "the nodes and the collect job reads them there";
  if (dir.find_first_of(" \t\n\r'\"\\$`%") != std::string::npos)
    return dir +
           ": with --executor slurm the bench folder's path must not hold white space, quotes, "
           "backslashes, '$', '`' or '%' (it goes into #SBATCH lines, where Slurm expands %)";
  return std::nullopt;
}

BenchFolderLock::BenchFolderLock(const std::string& dir, double wait_s) {
  io::ensure_directory(slurm_dir(dir));
  const std::string path = slurm_dir(dir) + "/.lock";
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw InputError(file_error(path, "cannot open the bench folder's lock"));
  const auto until = std::chrono::steady_clock::now() +
                     std::chrono::milliseconds(static_cast<long long>(wait_s * 1000.0));
  while (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    if (errno != EWOULDBLOCK && errno != EINTR) {
      ::close(fd_);
      throw InputError(file_error(path, "cannot lock the bench folder"));
    }
    if (std::chrono::steady_clock::now() >= until) {
      ::close(fd_);
      throw InputError(dir + ": another mcslam bench command is submitting into this folder " +
                       "(it holds " + path + "); try again when it has finished");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

BenchFolderLock::~BenchFolderLock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the lock
}

Submission submit(const std::string& dir, const std::string& executable, const SlurmTools& tools,
                  const SlurmOptions& options, const std::vector<int>& tasks) {
  if (auto e = check_slurm_folder(dir)) throw InputError(*e);
  if (tools.sbatch.empty()) throw InputError("no sbatch on PATH");
  io::ensure_directory(slurm_dir(dir));
  ScriptInput in{dir, executable, options, 1, tasks, ""};
  const std::vector<Submission> earlier = read_submissions(dir);
  if (!earlier.empty()) in.number = earlier.back().number + 1;
  const std::string base = slurm_dir(dir) + "/";
  const std::string runs = base + "runs-" + std::to_string(in.number) + ".sbatch";
  const std::string collect = base + "collect-" + std::to_string(in.number) + ".sbatch";
  io::write_file_atomic(runs, runs_script(in));
  Submission s{in.number, "", "", tasks, utc_now()};
  try {
    s.array_job = sbatch(tools, runs);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + "; nothing was submitted");
  }
  in.array_job = s.array_job;
  io::write_file_atomic(collect, collect_script(in));
  try {
    s.collect_job = sbatch(tools, collect);
  } catch (const InputError& e) {
    append_submission(dir, s);
    throw InputError(std::string(e.what()) + "; job array " + s.array_job +
                     " was submitted: once it has ended, run mcslam bench --collect " + dir);
  }
  append_submission(dir, s);
  return s;
}

std::map<int, std::string> parse_sacct(const std::string& output, const std::string& array_job) {
  return parse_pairs(output, array_job);
}

std::map<int, std::string> parse_squeue(const std::string& output, const std::string& array_job) {
  return parse_pairs(output, array_job);
}

std::optional<std::string> state_in_output(const std::string& text) {
  const std::pair<const char*, const char*> marks[] = {
      {"DUE TO TIME LIMIT", "TIMEOUT"},
      {"DUE TO PREEMPTION", "PREEMPTED"},
      {"DUE TO NODE FAILURE", "NODE_FAIL"},
      {"oom_kill event", "OUT_OF_MEMORY"},
      {"Exceeded job memory limit", "OUT_OF_MEMORY"},
  };
  for (const auto& [mark, state] : marks)
    if (text.find(mark) != std::string::npos) return std::string(state);
  if (text.find("CANCELLED AT") != std::string::npos) return std::string("CANCELLED");
  return std::nullopt;
}

std::string task_output_path(const std::string& dir, const std::string& array_job, int task) {
  return slurm_dir(dir) + "/task-" + array_job + "_" + std::to_string(task) + ".out";
}

TaskStates query_states(const std::string& dir, const std::vector<Submission>& submissions,
                        const std::vector<int>& tasks, const SlurmTools& tools) {
  TaskStates out;
  std::set<std::string> job_set;
  for (int t : tasks)
    if (const Submission* s = latest_with(submissions, t)) job_set.insert(s->array_job);
  if (job_set.empty()) return out;
  const std::vector<std::string> jobs(job_set.begin(), job_set.end());
  const auto sacct = sacct_states(jobs, tools, out.sacct_note);
  std::map<std::string, std::map<int, std::string>> queued;
  if (!sacct)
    for (const std::string& job : jobs) queued[job] = squeue_states(job, tools);
  for (int t : tasks) {
    const Submission* s = latest_with(submissions, t);
    if (!s) continue;
    TaskState state{"", s->array_job + "_" + std::to_string(t), ""};
    const auto& found = sacct ? sacct->at(s->array_job) : queued[s->array_job];
    if (const auto it = found.find(t); it != found.end()) {
      state.state = it->second;
      state.source = sacct ? "sacct" : "squeue";
    } else if (const auto in_output =
                   state_in_output(read_text(task_output_path(dir, s->array_job, t)))) {
      state = {*in_output, state.job, "its output"};
    }
    out.by_task[t] = state;
  }
  return out;
}

bool still_active(const std::string& state) {
  static const std::set<std::string> active = {
      "PENDING",    "RUNNING",      "REQUEUED",    "RESIZING",  "SUSPENDED", "CONFIGURING",
      "COMPLETING", "REQUEUE_HOLD", "REQUEUE_FED", "SIGNALING", "STAGE_OUT", "STOPPED"};
  return active.count(state) > 0;
}

}  // namespace mcslam::app::bench
