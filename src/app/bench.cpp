#include "mcslam/app/bench.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "mcslam/app/bench/plan.hpp"
#include "mcslam/app/bench/plan_file.hpp"
#include "mcslam/app/bench/process.hpp"
#include "mcslam/app/bench/scoreboard.hpp"
#include "mcslam/app/bench/slurm.hpp"
#include "mcslam/app/bench/task.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::app {

std::optional<std::string> BenchRequest::check() const {
  if (data_roots.empty()) return "give at least one DATA_ROOT folder";
  if (runs < 1) return "--runs: must be at least 1";
  if (max_frames < 0) return "--max-frames: must not be negative";
  if (overlays < 0) return "--overlays: must not be negative";
  if (confidence && !(*confidence > 0 && *confidence < 1)) return "--confidence: must be in (0, 1)";
  if (jobs < 1) return "--jobs: must be at least 1";
  if (executor == BenchExecutor::kLocal) {
    const SlurmOptions none;
    if (slurm.partition != none.partition || slurm.time_limit_min != none.time_limit_min ||
        slurm.array_limit != none.array_limit || !slurm.sbatch_args.empty())
      return "--partition, --time-limit, --array-limit and --sbatch-arg: only with --executor "
             "slurm";
    return std::nullopt;
  }
  if (jobs != 1)
    return "--jobs: only with --executor local (Slurm runs the tasks; --array-limit caps how "
           "many run at once)";
  if (auto e = bench::check_slurm_folder(output_dir)) return "--output " + *e;
  return slurm.check();
}

namespace {

namespace fs = std::filesystem;
using namespace bench;

std::string path_variable() {
  const char* path = std::getenv("PATH");
  return path ? path : "";
}

/// The bench's settings from a checked request: sequences found, configurations and modes.
/// For Slurm, every path is made absolute: the tasks and the collect job do not start in the
/// folder the bench was submitted from.
BenchSettings settings_for(BenchRequest request) {
  if (request.executor == BenchExecutor::kSlurm) {
    for (std::string& root : request.data_roots) root = fs::absolute(root).string();
    if (request.model) request.model = fs::absolute(*request.model).string();
  }
  if (request.model) {
    std::error_code ec;
    if (!fs::is_regular_file(*request.model, ec))
      throw InputError(file_error(*request.model, "no such model file (--model)"));
  }
  BenchSettings s;
  s.command = request.command_line;
  s.created_utc = utc_now();
  s.executor = request.executor;
  s.jobs = request.jobs;
  s.runs = request.runs;
  s.configs = select_configs(request.configs);
  s.modes = select_modes(request.modes);
  s.sequences = filter_sequences(discover_sequences(request.data_roots, request.output_dir),
                                 request.sequences);
  if (s.sequences.empty()) {
    std::string roots;
    for (const auto& r : request.data_roots) roots += (roots.empty() ? "" : ", ") + r;
    throw InputError(roots +
                     ": no TUM-layout sequence (a folder with rgb.txt and depth.txt) in it");
  }
  s.model = request.model;
  s.confidence = request.confidence;
  s.max_frames = request.max_frames;
  s.timeout_s = request.timeout_s;
  s.overlays = request.overlays;
  s.slurm = request.slurm;
  return s;
}

/// A bench planned and its plan written into the output folder.
struct Prepared {
  BenchSettings settings;
  Scoreboard board;
  std::vector<PlannedRun> runs;
};

Prepared prepare(const BenchRequest& request) {
  if (auto e = request.check()) throw InputError(*e);
  BenchSettings settings = settings_for(request);
  io::ensure_directory(request.output_dir);
  Scoreboard board(settings);
  std::vector<PlannedRun> runs = board.plan(request.output_dir);
  write_plan_files(request.output_dir, {settings, runs});
  forget_submissions(request.output_dir);
  return {std::move(settings), std::move(board), std::move(runs)};
}

std::string minutes(double seconds) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(1);
  if (seconds < 90)
    s << seconds << " s";
  else
    s << seconds / 60.0 << " min";
  return s.str();
}

std::string relative_to(const std::string& path, const std::string& dir) {
  return fs::path(path).lexically_relative(dir).string();
}

std::string slurm_text(const TaskState& s, const std::string& sacct_note) {
  if (s.state.empty())
    return "Slurm: state unknown (job " + s.job + (sacct_note.empty() ? "" : "; " + sacct_note) +
           ")";
  return "Slurm: " + s.state + " (job " + s.job + ", from " + s.source + ")";
}

std::string missing_text(const std::string& dir, const PlannedRun& run, const TaskState* slurm) {
  if (!slurm)
    return "no result: the run did not end (no " + relative_to(task_record_path(dir, run), dir) +
           ")";
  if (still_active(slurm->state)) return "no result yet: the task is " + slurm->state;
  if (slurm->state == "TIMEOUT") return "no result: Slurm ended the task at its time limit";
  return "no result: the task ended without a record of its run";
}

/// What the k-th run gets in the failed-runs table: the reason, the Slurm state when the run
/// was a Slurm task, and the log to read. Empty for a run that succeeded.
std::string failure_of(const std::string& dir, std::size_t k, const PlannedRun& run,
                       const std::optional<TaskRecord>& record, const TaskState* slurm,
                       const std::string& sacct_note) {
  if (record && record->ok()) return "";
  std::string text =
      record ? (record->error.empty() ? "failed" : record->error) : missing_text(dir, run, slurm);
  std::string log = relative_to(run_log(dir, run), dir);
  if (slurm) {
    text += "; " + slurm_text(*slurm, sacct_note);
    const std::string array_job = slurm->job.substr(0, slurm->job.find('_'));
    if (!record) log = relative_to(task_output_path(dir, array_job, static_cast<int>(k)), dir);
  }
  return text + "; log: " + log;
}

std::string executor_text(const BenchSettings& s, const std::vector<Submission>& submissions) {
  if (s.executor == BenchExecutor::kSlurm) {
    std::string ids;
    for (const Submission& sub : submissions) ids += (ids.empty() ? "" : ", ") + sub.array_job;
    if (ids.empty()) return "Slurm (not submitted)";
    return (submissions.size() == 1 ? "Slurm job array " : "Slurm job arrays ") + ids;
  }
  if (s.jobs > 1)
    return std::to_string(s.jobs) +
           " runs at once on this machine (speed figures measured while runs shared its CPUs)";
  return "";
}

BenchMeta meta_for(const BenchSettings& s) {
  BenchMeta meta;
  meta.created_utc = s.created_utc;
  meta.command = s.command;
  meta.hostname = host_name();
  meta.cpus = static_cast<int>(std::thread::hardware_concurrency());
  meta.runs_per_mode = s.runs;
  meta.modes = s.modes;
  meta.executor = executor_text(s, {});
  return meta;
}

using Clock = std::chrono::steady_clock;

/// One line per run on stderr: "[k/n] sequence · configuration · mode i/runs ... figures".
/// One run at a time, the line starts when the run does; with several at once, it is written
/// whole when the run ends.
class Progress {
 public:
  Progress(bool enabled, const BenchSettings& settings, std::size_t total, bool live)
      : enabled_(enabled),
        settings_(settings),
        total_(total),
        live_(live),
        width_(static_cast<int>(std::to_string(total).size())) {}

  double elapsed() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

  void started(const PlannedRun& run) {
    if (!enabled_ || !live_) return;
    std::cerr << head(done_ + 1, run) << std::flush;
  }

  void finished(const PlannedRun& run, const RunRecord& record) {
    ++done_;
    if (!enabled_) return;
    std::ostringstream line;
    if (!live_) line << head(done_, run);
    if (!record.ok) {
      line << "FAILED: " << record.error;
    } else {
      line.setf(std::ios::fixed);
      if (record.ate_rmse_m) line << "ATE " << std::setprecision(4) << *record.ate_rmse_m << " m, ";
      if (record.tracked_ratio)
        line << "tracked " << std::setprecision(0) << 100 * *record.tracked_ratio << " %, ";
      if (record.fps) line << std::setprecision(1) << *record.fps << " fps, ";
      line << minutes(record.wall_s);
    }
    const double done = elapsed();
    const double left = done / done_ * (total_ - done_);
    std::cerr << line.str() << "  [" << minutes(done) << " elapsed"
              << (done_ < total_ ? ", about " + minutes(left) + " left" : std::string()) << "]\n";
  }

 private:
  std::string head(std::size_t n, const PlannedRun& run) const {
    std::string label = run.config;
    for (const Config& c : settings_.configs)
      if (c.name == run.config) label = c.label;
    char text[64];
    std::snprintf(text, sizeof(text), "[%*zu/%zu] ", width_, n, total_);
    return text + run.sequence + " · " + label + " · " + to_string(run.mode) + " " +
           std::to_string(run.index) + "/" + std::to_string(settings_.runs) + " ... ";
  }

  bool enabled_;
  const BenchSettings& settings_;
  std::size_t total_;
  bool live_;
  int width_;
  std::size_t done_ = 0;
  Clock::time_point start_ = Clock::now();
};

/// Runs tasks 0..n-1 on `jobs` threads: `run(k)` outside any lock, then `done(k, record)` under
/// one lock, in the order the runs end. The first exception stops the pool and is rethrown.
void run_pool(std::size_t n, int jobs, const std::function<TaskRecord(std::size_t)>& run,
              const std::function<void(std::size_t, const TaskRecord&)>& done) {
  std::atomic<std::size_t> next{0};
  std::mutex mutex;
  std::exception_ptr error;
  const auto worker = [&] {
    for (std::size_t k = next++; k < n; k = next++) {
      try {
        const TaskRecord record = run(k);
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) done(k, record);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
    }
  };
  std::vector<std::thread> threads;
  for (std::size_t i = 1; i < std::min(static_cast<std::size_t>(jobs), n); ++i)
    threads.emplace_back(worker);
  worker();
  for (std::thread& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

/// The tables and the report, once every run is in.
void finish(BenchOutcome& outcome, const Scoreboard& board, const std::string& dir,
            const BenchMeta& meta, const std::string& assets) {
  outcome.markdown = board.write_tables(dir, meta);
  outcome.report_path =
      board.write_report(dir, meta, outcome.markdown, assets, outcome.report_warning);
}

std::string assets_for(const std::string& given, const std::string& executable) {
  return given.empty() ? (fs::path(executable).parent_path() / "report").string() : given;
}

/// The executable the runs use: the request's, or this one.
std::string executable_for(const std::string& given) {
  const std::string exe = given.empty() ? current_executable() : given;
  if (exe.empty()) throw InputError("cannot find the mcslam executable to run (/proc/self/exe)");
  return exe;
}

std::string submitted_message(const std::string& dir, const Submission& s, std::size_t runs) {
  std::ostringstream m;
  m << "mcslam bench: submitted " << s.tasks.size() << " of " << runs << " runs as Slurm job array "
    << s.array_job << " (" << dir << "/slurm/runs-" << s.number << ".sbatch), and job "
    << s.collect_job << " to collect them after it (afterany)\n"
    << "  follow:      squeue --jobs=" << s.array_job << "," << s.collect_job << "\n"
    << "  afterwards:  sacct --jobs=" << s.array_job
    << " --format=JobID,State,Elapsed,ExitCode,NodeList\n"
    << "  results:     " << dir << "/results.md and report.html once job " << s.collect_job
    << " has ended (any time: mcslam bench --collect " << dir << ")\n"
    << "  failed runs: mcslam bench --resubmit-failed " << dir << "\n";
  return m.str();
}

/// The records of every run of a plan (nullopt: the run has none).
std::vector<std::optional<TaskRecord>> records_of(const std::string& dir, const PlanFiles& plan) {
  std::vector<std::optional<TaskRecord>> records;
  for (const PlannedRun& run : plan.runs)
    records.push_back(read_task_record(task_record_path(dir, run)));
  return records;
}

/// The plan lines without a successful record.
std::vector<int> unfinished(const std::vector<std::optional<TaskRecord>>& records) {
  std::vector<int> tasks;
  for (std::size_t k = 0; k < records.size(); ++k)
    if (!records[k] || !records[k]->ok()) tasks.push_back(static_cast<int>(k));
  return tasks;
}

/// The bench's meta for tables collected from run records: the hosts that ran them, and the
/// wall time from the first run's start to the last one's end.
BenchMeta collected_meta(const BenchSettings& s, const std::vector<Submission>& submissions,
                         const std::vector<std::optional<TaskRecord>>& records) {
  BenchMeta meta = meta_for(s);
  meta.executor = executor_text(s, submissions);
  std::set<std::string> hosts;
  double first = 0, last = 0;
  for (const auto& r : records) {
    if (!r || r->start_unix <= 0) continue;
    hosts.insert(r->host);
    meta.cpus = std::max(meta.cpus, r->cpus);
    first = first > 0 ? std::min(first, r->start_unix) : r->start_unix;
    last = std::max(last, r->end_unix);
  }
  std::string names;
  for (const std::string& h : hosts) names += (names.empty() ? "" : ", ") + h;
  if (!names.empty()) meta.hostname = names;
  meta.wall_time_s = last > first ? last - first : 0;
  return meta;
}

SlurmOptions merged(SlurmOptions base, const SlurmOptions& given) {
  if (!given.partition.empty()) base.partition = given.partition;
  if (given.time_limit_min > 0) base.time_limit_min = given.time_limit_min;
  if (given.array_limit > 0) base.array_limit = given.array_limit;
  if (!given.sbatch_args.empty()) base.sbatch_args = given.sbatch_args;
  return base;
}

SlurmTools slurm_tools(const std::string& what) {
  SlurmTools tools = SlurmTools::from_path(path_variable());
  if (tools.sbatch.empty())
    throw InputError(what +
                     ": no sbatch on PATH (run it where jobs are submitted to the cluster, "
                     "usually a login node, or install Slurm's client, Debian's slurm-client); "
                     "nothing was submitted");
  return tools;
}

}  // namespace

std::string list_sequences(const BenchRequest& request) {
  BenchRequest listing = request;  // what would run, whoever runs it
  listing.executor = BenchExecutor::kLocal;
  listing.jobs = 1;
  listing.slurm = {};
  if (auto e = listing.check()) throw InputError(*e);
  const BenchSettings settings = settings_for(listing);
  std::ostringstream s;
  for (const Sequence& seq : settings.sequences)
    s << seq.name << "  " << to_string(seq.kind)
      << "  boxes: " << box_source_for(seq, request.model).describe() << "  " << seq.path << "\n";
  return s.str();
}

BenchOutcome run_bench(const BenchRequest& request) {
  if (request.executor != BenchExecutor::kLocal)
    throw InputError("run_bench runs on this machine: use submit_bench for Slurm");
  Prepared p = prepare(request);
  const std::string exe = executable_for(request.executable), &out = request.output_dir;
  BenchMeta meta = meta_for(p.settings);
  BenchOutcome outcome;
  outcome.sequences_not_run = p.board.sequences_not_run();
  if (request.progress)
    std::cerr << "mcslam bench: " << p.settings.sequences.size() << " sequence(s), "
              << p.settings.configs.size() << " configuration(s), " << p.runs.size() << " runs"
              << (request.jobs > 1 ? ", " + std::to_string(request.jobs) + " at once" : "")
              << "; results in " << out << "\n";
  Progress progress(request.progress, p.settings, p.runs.size(), request.jobs == 1);
  run_pool(
      p.runs.size(), request.jobs,
      [&](std::size_t k) {
        progress.started(p.runs[k]);
        return execute_run(out, p.runs[k], exe, request.timeout_s, "");
      },
      [&](std::size_t k, const TaskRecord& task) {
        const std::string failure = failure_of(out, k, p.runs[k], task, nullptr, "");
        const RunRecord& record = p.board.add(k, p.runs[k], out, failure, task.wall_s);
        ++outcome.runs;
        outcome.failed += record.ok ? 0 : 1;
        progress.finished(p.runs[k], record);
        meta.wall_time_s = progress.elapsed();
        p.board.write_tables(out, meta);
      });
  meta.wall_time_s = progress.elapsed();
  finish(outcome, p.board, out, meta, assets_for(request.report_assets, exe));
  return outcome;
}

SubmitOutcome submit_bench(const BenchRequest& request) {
  if (request.executor != BenchExecutor::kSlurm)
    throw InputError("submit_bench submits to Slurm: use run_bench on this machine");
  if (auto e = request.check()) throw InputError(*e);
  const SlurmTools tools = slurm_tools("--executor slurm");
  const std::string exe = executable_for(request.executable);
  const BenchFolderLock lock(request.output_dir);
  Prepared p = prepare(request);
  if (p.runs.empty())
    throw InputError(
        "nothing to submit: no sequence could be read, or every configuration was "
        "skipped (see " +
        request.output_dir + "/" + kPlanFile + ")");
  std::vector<int> tasks(p.runs.size());
  for (std::size_t k = 0; k < tasks.size(); ++k) tasks[k] = static_cast<int>(k);
  const Submission s = submit(request.output_dir, exe, tools, p.settings.slurm, tasks);
  return {static_cast<int>(tasks.size()), s.array_job, s.collect_job,
          submitted_message(request.output_dir, s, p.runs.size())};
}

SubmitOutcome resubmit_failed(const std::string& dir, const SlurmOptions& slurm) {
  if (!fs::path(dir).is_absolute())
    throw InputError("--resubmit-failed " + dir +
                     ": give the bench folder as an absolute path (the cluster's nodes use it)");
  if (auto e = slurm.check()) throw InputError(*e);
  if (auto e = check_slurm_folder(dir)) throw InputError("--resubmit-failed " + *e);
  const SlurmTools tools = slurm_tools("--resubmit-failed");
  // Held from the check of what still runs to the new submission: a second bench command on
  // the folder waits, then sees this one's jobs.
  const BenchFolderLock lock(dir);
  PlanFiles plan = read_plan_files(dir);
  for (const PlannedRun& run : plan.runs)
    if (!fs::path(run.output()).is_absolute())
      throw InputError(file_error((fs::path(dir) / kPlanFile).string(),
                                  run.describe() + " writes into the relative folder " +
                                      run.output() +
                                      ": Slurm's tasks need absolute paths (make the bench "
                                      "again with --executor slurm)"));
  const std::vector<int> candidates = unfinished(records_of(dir, plan));
  const TaskStates states = query_states(dir, read_submissions(dir), candidates, tools);
  std::vector<int> tasks;
  std::vector<std::string> unknown;  // submitted, but Slurm tells nothing of them
  std::size_t active = 0;
  for (int t : candidates) {
    const auto it = states.by_task.find(t);
    if (it == states.by_task.end()) {
      tasks.push_back(t);  // never submitted
    } else if (it->second.state.empty()) {
      // sacct and squeue failed or do not list it (yet): it may be queued or running, and a
      // duplicate would remove its run folder. Not resubmitted.
      unknown.push_back(it->second.job);
    } else if (still_active(it->second.state)) {
      ++active;
    } else {
      tasks.push_back(t);
    }
  }
  SubmitOutcome outcome;
  std::string busy =
      active ? std::to_string(active) + " run(s) still queued or running; " : std::string();
  if (!unknown.empty()) {
    std::string jobs;
    for (const std::string& j : unknown) jobs += (jobs.empty() ? "" : ", ") + j;
    busy += std::to_string(unknown.size()) + " run(s) whose state Slurm does not tell (" + jobs +
            (states.sacct_note.empty() ? "" : "; " + states.sacct_note) +
            "; squeue does not list them): they may still be queued or running, so they are "
            "not resubmitted (once they have surely ended, scancel them or check their "
            "slurm/task-*.out, and try again); ";
  }
  if (tasks.empty()) {
    outcome.message = "mcslam bench: nothing to resubmit: " + busy +
                      (active || !unknown.empty() ? "the others have" : "every run has") +
                      " a result\n";
    return outcome;
  }
  plan.settings.slurm = merged(plan.settings.slurm, slurm);
  plan.settings.executor = BenchExecutor::kSlurm;
  write_plan_files(dir, plan);
  const Submission s = submit(dir, executable_for(""), tools, plan.settings.slurm, tasks);
  outcome = {static_cast<int>(tasks.size()), s.array_job, s.collect_job,
             (busy.empty() ? "" : "mcslam bench: " + busy + "not resubmitted\n") +
                 submitted_message(dir, s, plan.runs.size())};
  return outcome;
}

BenchOutcome collect_bench(const std::string& dir, bool progress, const std::string& assets) {
  const PlanFiles plan = read_plan_files(dir);
  Scoreboard board(plan.settings);
  for (std::size_t k = 0; k < plan.runs.size(); ++k)
    if (auto e = board.check(plan.runs[k]))
      throw InputError(file_error((fs::path(dir) / kPlanFile).string(),
                                  "run " + plan.runs[k].describe() + ": " + *e));
  const auto records = records_of(dir, plan);
  const std::vector<Submission> submissions = read_submissions(dir);
  const TaskStates states =
      query_states(dir, submissions, unfinished(records), SlurmTools::from_path(path_variable()));
  BenchOutcome outcome;
  outcome.sequences_not_run = board.sequences_not_run();
  for (std::size_t k = 0; k < plan.runs.size(); ++k) {
    const auto it = states.by_task.find(static_cast<int>(k));
    const TaskState* slurm = it == states.by_task.end() ? nullptr : &it->second;
    const std::string failure =
        failure_of(dir, k, plan.runs[k], records[k], slurm, states.sacct_note);
    const RunRecord& r =
        board.add(k, plan.runs[k], dir, failure, records[k] ? records[k]->wall_s : 0.0);
    ++outcome.runs;
    outcome.failed += r.ok ? 0 : 1;
    if (progress && !r.ok)
      std::cerr << "mcslam bench: " << plan.runs[k].describe() << ": " << r.error << "\n";
  }
  const BenchMeta meta = collected_meta(plan.settings, submissions, records);
  finish(outcome, board, dir, meta, assets_for(assets, current_executable()));
  return outcome;
}

int run_bench_task(const std::string& dir, int index) {
  const PlanFiles plan = read_plan_files(dir);
  if (index < 0 || static_cast<std::size_t>(index) >= plan.runs.size())
    throw InputError(file_error((fs::path(dir) / kPlanFile).string(),
                                "has no run " + std::to_string(index) + " (its " +
                                    std::to_string(plan.runs.size()) + " runs are 0 to " +
                                    std::to_string(plan.runs.size() - 1) + ")"));
  const PlannedRun& run = plan.runs[static_cast<std::size_t>(index)];
  const char* job = std::getenv("SLURM_ARRAY_JOB_ID");
  const char* task = std::getenv("SLURM_ARRAY_TASK_ID");
  const std::string slurm_job = job && task ? std::string(job) + "_" + task : std::string();
  std::cout << "mcslam bench: run " << index << " of " << dir << ": " << run.describe() << " on "
            << host_name() << std::endl;
  const TaskRecord record =
      execute_run(dir, run, executable_for(""), plan.settings.timeout_s, slurm_job);
  std::cout << "mcslam bench: "
            << (record.ok() ? "done in " + minutes(record.wall_s) : "FAILED: " + record.error)
            << " (log " << run_log(dir, run) << ")" << std::endl;
  return record.ok() ? 0 : 2;
}

}  // namespace mcslam::app
