// `mcslam bench DATA_ROOT...`: every sequence under the roots, N runs per configuration and mode,
// here or on a Slurm cluster; also a bench folder's collect, resubmission and single tasks.
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "command.hpp"
#include "mcslam/app/bench.hpp"
#include "mcslam/core/error.hpp"
#include "shared_options.hpp"

namespace mcslam::cli {
namespace {

/// What `mcslam bench` was asked beyond a bench: collect, resubmit or run one task of a plan.
struct BenchActions {
  std::string executor = "local";
  std::string collect, resubmit;
  std::vector<std::string> task;  // DIR INDEX
};

/// The command as typed, quoted where a shell would need it.
std::string command_line(int argc, char** argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool plain = !arg.empty() && arg.find_first_of(" \t'\"$\\;&|<>*?()") == std::string::npos;
    if (!line.empty()) line += ' ';
    if (plain) {
      line += arg;
    } else {
      line += '\'';
      for (char c : arg) line += c == '\'' ? std::string("'\\''") : std::string(1, c);
      line += '\'';
    }
  }
  return line;
}

/// The tables' summary after a local bench or a collect: 0 when every run succeeded, else 2.
int report_bench(const app::BenchOutcome& outcome, const std::string& dir, bool quiet) {
  if (!quiet) std::cout << "\n" << outcome.markdown << "\n";
  if (!outcome.report_warning.empty())
    std::cerr << "mcslam bench: warning: " << outcome.report_warning << "\n";
  std::cerr << "mcslam bench: " << outcome.runs - outcome.failed << " of " << outcome.runs
            << " runs succeeded; tables in " << dir << " (results.md, results.json, runs.csv"
            << (outcome.report_path.empty() ? "" : ", report.html") << ")\n";
  if (outcome.failed > 0 || outcome.sequences_not_run > 0) {
    std::cerr << "mcslam bench: " << outcome.failed << " run(s) failed and "
              << outcome.sequences_not_run
              << " sequence(s) could not be read; see \"Failed runs\" in results.md\n";
    return 2;
  }
  return 0;
}

/// --run-task's INDEX (InputError when it is not a number from 0).
int task_index(const std::string& text) {
  const std::optional<int> index = parse_int(text);
  if (!index || *index < 0)
    throw InputError("--run-task: '" + text + "' is not a run number (0, 1, ...)");
  return *index;
}

/// --collect, --resubmit-failed or --run-task on a bench folder; nullopt when none was given.
std::optional<int> bench_folder_action(const app::BenchRequest& request,
                                       const BenchActions& actions, bool quiet) {
  const int given = !actions.collect.empty() + !actions.resubmit.empty() + !actions.task.empty();
  if (given == 0) return std::nullopt;
  if (given > 1) throw InputError("--collect, --resubmit-failed and --run-task exclude each other");
  if (!request.data_roots.empty())
    throw InputError(
        "--collect, --resubmit-failed and --run-task take a bench folder and no DATA_ROOT (the "
        "folder's plan says what runs)");
  if (!actions.collect.empty())
    return report_bench(app::collect_bench(actions.collect, !quiet, request.report_assets),
                        actions.collect, quiet);
  if (!actions.resubmit.empty()) {
    std::cout << app::resubmit_failed(actions.resubmit, request.slurm).message;
    return 0;
  }
  return app::run_bench_task(actions.task.at(0), task_index(actions.task.at(1)));
}

class BenchCommand : public Command {
 public:
  explicit BenchCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "bench",
            "Run every TUM-layout sequence under DATA_ROOT N times per ablation configuration "
            "(sequential for accuracy, threaded for speed), here or on a Slurm cluster; tables "
            "and report.html")) {
    add_plan_options(app());
    add_executor_options(app());
    app()->add_flag("--quiet,-q", quiet_, "No per-run progress and no tables on stdout");
  }

  int run(int argc, char** argv) override {
    request_.progress = !quiet_;
    request_.command_line = command_line(argc, argv);
    if (actions_.executor == "slurm") request_.executor = app::BenchExecutor::kSlurm;
    if (request_.list_only) {
      std::cout << app::list_sequences(request_);
      return 0;
    }
    if (const auto code = bench_folder_action(request_, actions_, quiet_)) return *code;
    if (request_.data_roots.empty()) throw InputError("bench: give at least one DATA_ROOT");
    if (request_.output_dir.empty()) throw InputError("bench: --output is required");
    if (request_.executor == app::BenchExecutor::kSlurm) {
      std::cout << app::submit_bench(request_).message;
      return 0;
    }
    return report_bench(app::run_bench(request_), request_.output_dir, quiet_);
  }

 private:
  /// The sequences, configurations, modes and figures of the runs.
  void add_plan_options(CLI::App* cmd) {
    cmd->add_option("data_root", request_.data_roots,
                    "Folder(s) searched for sequences (folders with rgb.txt and depth.txt)");
    cmd->add_option("--output,-o", request_.output_dir,
                    "Folder for the results (required unless --list)");
    cmd->add_option("--runs,-n", request_.runs, "Runs per configuration and mode (default 3)");
    cmd->add_option("--configs", request_.configs,
                    "Comma-separated subset of points,lines,planes,detection,full (default all)")
        ->delimiter(',');
    cmd->add_option("--modes", request_.modes,
                    "Comma-separated subset of sequential,threaded,realtime (default: "
                    "sequential,threaded; realtime: threaded with --realtime)")
        ->delimiter(',');
    cmd->add_option("--sequences", request_.sequences,
                    "Only sequences whose name contains one of these (comma-separated)")
        ->delimiter(',');
    cmd->add_option("--model", request_.model,
                    "ONNX detector for the detection and full configurations (a sequence's "
                    "own detections.json is used first)");
    cmd->add_option("--confidence", request_.confidence, "Detector confidence threshold");
    cmd->add_option("--max-frames", request_.max_frames, "Frames per run (default all)");
    cmd->add_option("--timeout", request_.timeout_s,
                    "Seconds after which a run is stopped and reported failed (0: none; "
                    "default 3600)");
    cmd->add_option("--overlays", request_.overlays,
                    "Annotated frames per sequence in report.html (default 6)");
    cmd->add_option("--report-assets", request_.report_assets,
                    "Folder with report.js (default: report/ beside the mcslam binary)");
    cmd->add_flag("--list", request_.list_only, "Print the sequences found and stop");
  }

  /// Who runs the runs (here or Slurm) and the actions on a bench folder.
  void add_executor_options(CLI::App* cmd) {
    cmd->add_option("--executor", actions_.executor,
                    "Who runs the runs: local (this machine, the default) or slurm (one Slurm job "
                    "array, and a job collecting the results after it)")
        ->check(CLI::IsMember({"local", "slurm"}));
    cmd->add_option("--jobs,-j", request_.jobs,
                    "Local executor: runs at once (default 1; more share the CPUs, and the "
                    "tables say so)");
    cmd->add_option("--partition", request_.slurm.partition, "Slurm partition (sbatch default)");
    cmd->add_option("--time-limit", request_.slurm.time_limit_min,
                    "Slurm time limit of each run's task, in minutes (partition default)");
    cmd->add_option("--array-limit", request_.slurm.array_limit,
                    "Slurm tasks running at once (default: no limit)");
    cmd->add_option("--sbatch-arg", request_.slurm.sbatch_args,
                    "Another sbatch option for the batch scripts, e.g. "
                    "--sbatch-arg=--cpus-per-task=2 (repeatable)");
    cmd->add_option("--collect", actions_.collect,
                    "Score the runs of bench folder DIR and write its tables and report "
                    "(what the Slurm collect job does)");
    cmd->add_option("--resubmit-failed", actions_.resubmit,
                    "Submit again to Slurm the runs of bench folder DIR that have no result");
    cmd->add_option("--run-task", actions_.task,
                    "DIR INDEX: run line INDEX (from 0) of DIR/plan.tsv (what each Slurm array "
                    "task does)")
        ->expected(2);
  }

  app::BenchRequest request_;
  BenchActions actions_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> make_bench_command(CLI::App& cli) {
  return std::make_unique<BenchCommand>(cli);
}

}  // namespace mcslam::cli
