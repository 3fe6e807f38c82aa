// Tests of the bench's executors apart from the runs themselves: the plan files (bench.json and
// plan.tsv) and their parser's errors, the request's checks, and Slurm driven through fake
// sbatch, sacct and squeue scripts (submission, rejection, missing sbatch, task states). The
// real cluster is tests/app/bench_slurm.sh.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <string>
#include <vector>

#include "mcslam/app/bench.hpp"
#include "mcslam/app/bench/plan_file.hpp"
#include "mcslam/app/bench/process.hpp"
#include "mcslam/app/bench/slurm.hpp"
#include "mcslam/app/bench/task.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"

namespace mcslam::app::bench {
namespace {

namespace fs = std::filesystem;
using test::contains;
using test::expect_input_error;
using test::TempDir;

BenchSettings two_sequences() {
  BenchSettings s;
  s.command = "mcslam bench /data --runs 2 --output /out";
  s.created_utc = "2026-11-27T10:00:00Z";
  s.runs = 2;
  s.modes = {Mode::kSequential, Mode::kThreaded};
  s.configs = select_configs({"points", "full"});
  for (const char* name : {"room_a", "room_b"}) {
    Sequence q;
    q.name = name;
    q.path = std::string("/data/") + name;
    q.kind = DatasetKind::kSynthetic;
    s.sequences.push_back(q);
  }
  s.sequences[1].detections_file = "/data/room_b/detections.json";
  return s;
}

PlannedRun planned(const std::string& sequence, const std::string& config, Mode mode, int i) {
  PlannedRun run{sequence, config, mode, i, {}};
  run.arguments = {"run",
                   "/data/" + sequence,
                   "--output",
                   "/out/" + run.folder(),
                   mode == Mode::kSequential ? "--sequential" : "--threaded",
                   "--features",
                   "points",
                   "--quiet"};
  return run;
}

/// An executable shell script in `dir`/bin.
void fake_command(const TempDir& dir, const std::string& name, const std::string& body) {
  const std::string path = dir.write("bin/" + name, "#!/bin/sh\n" + body);
  chmod(path.c_str(), 0755);
}

// --- plan files ---------------------------------------------------------------------------------

TEST(BenchPlanFile, SettingsAndRunsRoundTrip) {
  const BenchSettings s = two_sequences();
  const BenchSettings back = parse_settings(settings_json(s).dump(), "bench.json");
  EXPECT_EQ(back.command, s.command);
  EXPECT_EQ(back.runs, 2);
  EXPECT_EQ(back.modes, s.modes);
  ASSERT_EQ(back.configs.size(), 2u);
  EXPECT_EQ(back.configs[1].name, "full");
  ASSERT_EQ(back.sequences.size(), 2u);
  EXPECT_EQ(back.sequences[1].detections_file, "/data/room_b/detections.json");
  EXPECT_EQ(back.sequences[0].kind, DatasetKind::kSynthetic);

  const std::vector<PlannedRun> runs = {planned("room_a", "points", Mode::kSequential, 1),
                                        planned("room_b", "full", Mode::kThreaded, 2)};
  const std::string tsv = plan_tsv(runs);
  // One line per run: sequence, config, mode, index and the arguments, tab-separated.
  EXPECT_TRUE(contains(tsv,
                       "\nroom_b\tfull\tthreaded\t2\trun\t/data/room_b\t--output\t/out/runs/"
                       "room_b/full/threaded-2\t--threaded\t"))
      << tsv;
  const auto parsed = parse_plan(tsv, "plan.tsv", s);
  ASSERT_EQ(parsed.size(), 2u);
  EXPECT_EQ(parsed[1].folder(), "runs/room_b/full/threaded-2");
  EXPECT_EQ(parsed[1].arguments, runs[1].arguments);

  TempDir dir("bench_plan_file");
  write_plan_files(dir.str(), {s, runs});
  const PlanFiles files = read_plan_files(dir.str());
  EXPECT_EQ(files.runs.size(), 2u);
  EXPECT_EQ(files.settings.sequences[0].path, "/data/room_a");
}

TEST(BenchPlanFile, NonsenseLinesAreNamedWithFileAndLine) {
  const BenchSettings s = two_sequences();
  const std::string head = plan_tsv({});  // comments and the header row: 5 lines
  const std::string good =
      "room_a\tpoints\tsequential\t1\trun\t/data/room_a\t--output\t/out/runs/"
      "room_a/points/sequential-1\t--sequential";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"room_a points sequential 1 run /data/room_a", "found 1 column(s)"},
      {"room_c\tpoints\tsequential\t1\trun\t/d\t--output\t/o", "sequence 'room_c' is not one"},
      {"room_a\torb\tsequential\t1\trun\t/d\t--output\t/o", "configuration 'orb' is not one"},
      {"room_a\tpoints\trealtime\t1\trun\t/d\t--output\t/o", "mode 'realtime' is not one"},
      {"room_a\tpoints\tsequential\tone\trun\t/d\t--output\t/o", "index 'one' is not a number"},
      {"room_a\tpoints\tsequential\t3\trun\t/d\t--output\t/o", "from 1 to 2"},
      {"room_a\tpoints\tsequential\t1\teval\t/d\t--output\t/o", "must start with 'run'"},
      {"room_a\tpoints\tsequential\t1\trun\t/data/room_a\t--sequential", "no --output"},
      {"room_a\tpoints\tsequential\t1\trun\t/data/room_a\t--output\t/tmp/elsewhere\t--sequential",
       "is not the run's folder runs/room_a/points/sequential-1"},
      {"room_a\tpoints\tsequential\t1\trun\t/data/room_a\t--output\t/out/runs/room_a/points/"
       "sequential-1\t--threaded",
       "mode sequential does not match the arguments"},
      {"room_a\tpoints\tsequential\t1\trun\t\t--output\t/o", "an empty argument"},
      {good + "\n" + good, "room_a · points · sequential 1 is planned twice"},
  };
  for (const auto& [lines, message] : cases) {
    const std::string text = head + lines + "\n";  // (clang 14 cannot capture a binding)
    const std::string line = std::to_string(contains(message, "twice") ? 7 : 6);
    expect_input_error([&] { parse_plan(text, "/b/plan.tsv", s); },
                       {"/b/plan.tsv:" + line + ": ", message});
  }
  expect_input_error([&] { parse_plan("hello\n", "/b/plan.tsv", s); },
                     {"/b/plan.tsv:1: expected the header row"});
  expect_input_error([&] { parse_plan("# only comments\n", "/b/plan.tsv", s); },
                     {"/b/plan.tsv: no header row"});
  EXPECT_EQ(parse_plan(head + good + "\n\n# a note\n", "p", s).size(), 1u);
  expect_input_error([] { plan_tsv({planned("room\ta", "points", Mode::kSequential, 1)}); },
                     {"a tab or line break cannot go into plan.tsv"});
}

TEST(BenchPlanFile, MissingOrBrokenFilesAreNamed) {
  TempDir dir("bench_plan_file");
  expect_input_error([&] { read_plan_files(dir.str()); },
                     {dir.file("bench.json"), "no such file", "is not a bench folder"});
  dir.write("bench.json", "{\"format\": \"mcslam-bench-plan\", \"runs\": ");
  expect_input_error([&] { read_plan_files(dir.str()); },
                     {dir.file("bench.json"), "not a bench's settings"});
  nlohmann::json j = settings_json(two_sequences());
  j["modes"] = {"fast"};
  dir.write("bench.json", j.dump());
  expect_input_error([&] { read_plan_files(dir.str()); }, {dir.file("bench.json"), "'fast'"});
  j = settings_json(two_sequences());
  j["runs"] = 0;
  dir.write("bench.json", j.dump());
  expect_input_error([&] { read_plan_files(dir.str()); }, {"\"runs\" must be at least 1"});
  dir.write("bench.json", settings_json(two_sequences()).dump());
  expect_input_error([&] { read_plan_files(dir.str()); }, {dir.file("plan.tsv"), "no such file"});
}

// --- the request --------------------------------------------------------------------------------

TEST(BenchRequest, ChecksOptionsOfEachExecutor) {
  BenchRequest r;
  r.data_roots = {"/data"};
  r.output_dir = "out";
  EXPECT_FALSE(r.check());
  r.jobs = 0;
  EXPECT_TRUE(contains(r.check().value_or(""), "--jobs: must be at least 1"));
  r.jobs = 2;
  EXPECT_FALSE(r.check());
  r.slurm.partition = "debug";
  EXPECT_TRUE(contains(r.check().value_or(""), "only with --executor slurm"));

  r.executor = BenchExecutor::kSlurm;
  EXPECT_TRUE(contains(r.check().value_or(""), "--jobs: only with --executor local"));
  r.jobs = 1;
  EXPECT_TRUE(contains(r.check().value_or(""),
                       "--output out: with --executor slurm the bench "
                       "folder must be an absolute path"));
  EXPECT_TRUE(contains(r.check().value_or(""), "nodes share"));
  r.output_dir = "/shared/bench";
  EXPECT_FALSE(r.check());
  r.slurm.time_limit_min = -1;
  EXPECT_TRUE(contains(r.check().value_or(""), "--time-limit: must not be negative"));
  r.slurm.time_limit_min = 30;
  r.slurm.sbatch_args = {"mem=4G"};
  EXPECT_TRUE(contains(r.check().value_or(""), "--sbatch-arg: 'mem=4G' is not one sbatch option"));
  r.slurm.sbatch_args = {"--mem=4G"};
  EXPECT_FALSE(r.check());
}

// --- Slurm --------------------------------------------------------------------------------------

TEST(BenchSlurm, TaskListsAndJobIds) {
  EXPECT_EQ(task_list({0, 1, 2, 3}), "0-3");
  EXPECT_EQ(task_list({5, 1, 3, 4}), "1,3-5");
  EXPECT_EQ(parse_task_list("1,3-5"), (std::vector<int>{1, 3, 4, 5}));
  EXPECT_EQ(parse_task_list("[4-6%2]"), (std::vector<int>{4, 5, 6}));
  EXPECT_FALSE(parse_task_list("3-1"));
  EXPECT_FALSE(parse_task_list("a"));
  EXPECT_FALSE(parse_task_list(""));
  EXPECT_EQ(parse_job_id("17\n"), "17");
  EXPECT_EQ(parse_job_id("sbatch: warning: something\n18;cluster\n"), "18");
  EXPECT_FALSE(parse_job_id("sbatch: error: invalid partition specified: nope\n"));
}

TEST(BenchSlurm, ScriptsSayWhatTheyRun) {
  ScriptInput in{"/shared/b", "/opt/mcslam/bin/mcslam", {}, 2, {0, 1, 2, 5}, "17"};
  in.options.partition = "gpu";
  in.options.time_limit_min = 30;
  in.options.array_limit = 4;
  in.options.sbatch_args = {"--cpus-per-task=2", "--mem=4G"};
  const std::string runs = runs_script(in);
  EXPECT_EQ(runs.rfind("#!/bin/bash\n", 0), 0u);
  for (const char* line :
       {"#SBATCH --array=0-2,5%4\n", "#SBATCH --output=\"/shared/b/slurm/task-%A_%a.out\"\n",
        "#SBATCH --partition=gpu\n", "#SBATCH --time=30\n", "#SBATCH --cpus-per-task=2\n",
        "#SBATCH --mem=4G\n",
        "exec '/opt/mcslam/bin/mcslam' bench --run-task '/shared/b' \"$SLURM_ARRAY_TASK_ID\"\n"})
    EXPECT_TRUE(contains(runs, line)) << line << "\n" << runs;
  const std::string collect = collect_script(in);
  for (const char* line : {"#SBATCH --dependency=afterany:17\n", "#SBATCH --partition=gpu\n",
                           "exec '/opt/mcslam/bin/mcslam' bench --collect '/shared/b' --quiet\n"})
    EXPECT_TRUE(contains(collect, line)) << line << "\n" << collect;
}

TEST(BenchSlurm, SubmitsTheArrayThenTheCollectJobAfterIt) {
  TempDir dir("bench_slurm");
  fake_command(dir, "sbatch",
               "echo \"$@\" >> \"$(dirname \"$0\")/calls.txt\"\n"
               "case \"$2\" in *collect*) echo 43;; *) echo 'sbatch: warning: x' >&2; echo 42;; "
               "esac\n");
  const SlurmTools tools = SlurmTools::from_path(dir.file("bin"));
  EXPECT_EQ(tools.sbatch, dir.file("bin/sbatch"));
  EXPECT_TRUE(tools.sacct.empty());
  const std::string b = dir.file("b");
  fs::create_directories(b);
  Submission s = submit(b, "/x/mcslam", tools, {}, {0, 1, 2});
  EXPECT_EQ(s.array_job, "42");
  EXPECT_EQ(s.collect_job, "43");
  EXPECT_EQ(s.number, 1);
  EXPECT_TRUE(contains(test::read_file(dir / "b/slurm/collect-1.sbatch"), "afterany:42"));
  s = submit(b, "/x/mcslam", tools, {}, {2});
  EXPECT_EQ(s.number, 2);
  const auto all = read_submissions(b);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].tasks, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(all[1].tasks, (std::vector<int>{2}));
  const std::string calls = test::read_file(dir / "bin/calls.txt");
  EXPECT_TRUE(contains(calls, "--parsable " + b + "/slurm/runs-1.sbatch\n"));
  EXPECT_TRUE(contains(calls, "--parsable " + b + "/slurm/collect-2.sbatch\n"));
}

TEST(BenchSlurm, RejectedSubmissionsAndNoSbatchAreClearErrors) {
  TempDir dir("bench_slurm");
  const std::string b = dir.file("b");
  fs::create_directories(b);
  expect_input_error([&] { submit(b, "/x/mcslam", SlurmTools::from_path(""), {}, {0}); },
                     {"no sbatch on PATH"});
  fake_command(dir, "sbatch",
               "echo 'sbatch: error: invalid partition specified: nope' >&2\n"
               "echo 'sbatch: error: Batch job submission failed: Invalid partition name "
               "specified' >&2\nexit 1\n");
  SlurmOptions bad;
  bad.partition = "nope";
  expect_input_error(
      [&] { submit(b, "/x/mcslam", SlurmTools::from_path(dir.file("bin")), bad, {0}); },
      {"sbatch rejected " + b +
       "/slurm/runs-1.sbatch: sbatch: error: invalid partition "
       "specified: nope; sbatch: error: Batch job submission failed"});
  EXPECT_TRUE(read_submissions(b).empty());  // nothing was submitted

  // The array accepted, its collect job rejected: the array stays, and the error says so.
  fake_command(dir, "sbatch",
               "case \"$2\" in *collect*) echo 'sbatch: error: Job dependency problem' >&2; "
               "exit 1;; *) echo 42;; esac\n");
  expect_input_error(
      [&] { submit(b, "/x/mcslam", SlurmTools::from_path(dir.file("bin")), {}, {0}); },
      {"collect-1.sbatch: sbatch: error: Job dependency problem", "job array 42 was submitted",
       "mcslam bench --collect " + b});
  ASSERT_EQ(read_submissions(b).size(), 1u);
  dir.write("b/slurm/jobs.tsv", "1\tx\t\t0\tnow\n");
  expect_input_error([&] { read_submissions(b); }, {b + "/slurm/jobs.tsv:1: "});
}

TEST(BenchSlurm, FoldersThatBreakTheJobScriptsAreRefusedBySubmit) {
  // Slurm expands %x, %u, ... in --output, and white space or quotes break the #SBATCH lines:
  // submit() refuses such a folder whoever calls it (the first submission or a resubmission).
  for (const char* dir : {"/shared/my bench", "/shared/b%x", "/shared/new\nline", "/shared/q'uote",
                          "/shared/d$HOME", "relative/b"}) {
    EXPECT_TRUE(check_slurm_folder(dir).has_value()) << dir;
    expect_input_error([&] { submit(dir, "/x/mcslam", SlurmTools::from_path(""), {}, {0}); },
                       {"bench folder"});
  }
  EXPECT_FALSE(check_slurm_folder("/shared/bench-2026_12.01"));
}

TEST(BenchSlurm, TwoCommandsOnOneFolderTakeTurns) {
  TempDir dir("bench_lock");
  const std::string b = dir.file("b");
  fs::create_directories(b);
  {
    const BenchFolderLock first(b);
    expect_input_error([&] { BenchFolderLock second(b, 0.2); },
                       {"another mcslam bench command", b + "/slurm/.lock"});
  }
  const BenchFolderLock again(b, 0.2);  // released with the first
}

// A task that was submitted but that sacct and squeue do not list (they failed, or the
// controller has not listed it yet) may be running: a duplicate would remove its run folder.
TEST(BenchSlurm, ResubmissionLeavesTasksWhoseStateIsUnknown) {
  TempDir dir("bench_resubmit");
  const std::string b = dir.file("b");
  PlanFiles plan;
  plan.settings = two_sequences();
  plan.settings.executor = BenchExecutor::kSlurm;
  plan.runs = {planned("room_a", "points", Mode::kSequential, 1),
               planned("room_b", "points", Mode::kSequential, 1)};
  fs::create_directories(b);
  write_plan_files(b, plan);
  dir.write("b/slurm/jobs.tsv", "1\t42\t43\t0-1\tt\n");
  fake_command(dir, "sbatch",
               "echo \"$@\" >> \"$(dirname \"$0\")/calls.txt\"\n"
               "case \"$2\" in *collect*) echo 51;; *) echo 50;; esac\n");
  fake_command(dir, "sacct", "echo 'sacct: error: slurmdbd: connection refused' >&2; exit 1\n");
  fake_command(dir, "squeue", "exit 1\n");
  const char* old_path = std::getenv("PATH");
  const std::string saved = old_path ? old_path : "";
  setenv("PATH", (dir.file("bin") + ":" + saved).c_str(), 1);
  SubmitOutcome outcome = resubmit_failed(b, {});
  EXPECT_EQ(outcome.tasks, 0);
  EXPECT_TRUE(contains(outcome.message, "2 run(s) whose state Slurm does not tell (42_0, 42_1"))
      << outcome.message;
  EXPECT_TRUE(contains(outcome.message, "connection refused")) << outcome.message;
  EXPECT_FALSE(fs::exists(dir.file("bin/calls.txt")));  // nothing submitted

  // sacct answers: task 0 still runs, task 1 failed: only task 1 goes again.
  fake_command(dir, "sacct", "echo '42_0|RUNNING'; echo '42_1|FAILED'\n");
  outcome = resubmit_failed(b, {});
  setenv("PATH", saved.c_str(), 1);
  EXPECT_EQ(outcome.tasks, 1) << outcome.message;
  EXPECT_TRUE(contains(outcome.message, "1 run(s) still queued or running")) << outcome.message;
  EXPECT_TRUE(contains(test::read_file(dir / "b/slurm/runs-2.sbatch"), "#SBATCH --array=1\n"));
}

TEST(BenchSlurm, StatesFromSacctSqueueAndTheTaskOutput) {
  const std::string sacct =
      "42_0|COMPLETED\n42_0.batch|COMPLETED\n42_1|TIMEOUT\n42_1.batch|CANCELLED\n"
      "42_2|CANCELLED by 0\n42_[3-4%2]|PENDING\n41_7|FAILED\n";
  const auto states = parse_sacct(sacct, "42");
  EXPECT_EQ(states.size(), 5u);
  EXPECT_EQ(states.at(1), "TIMEOUT");
  EXPECT_EQ(states.at(2), "CANCELLED");
  EXPECT_EQ(states.at(4), "PENDING");
  EXPECT_EQ(parse_squeue("42_5|RUNNING\n42_6|PENDING\n", "42").at(5), "RUNNING");
  EXPECT_EQ(state_in_output("slurmstepd-n1: error: *** JOB 43 ON n1 CANCELLED AT "
                            "2026-11-27T03:54:29 DUE TO TIME LIMIT ***\n"),
            "TIMEOUT");
  EXPECT_EQ(state_in_output("*** JOB 43 ON n1 CANCELLED AT 2026-11-27T03:54:29 ***"), "CANCELLED");
  EXPECT_FALSE(state_in_output("mcslam bench: run 3 ...\n"));
  EXPECT_TRUE(still_active("PENDING"));
  EXPECT_FALSE(still_active("TIMEOUT"));
}

TEST(BenchSlurm, QueryFallsBackFromSacctToSqueueAndTheOutput) {
  TempDir dir("bench_slurm");
  const std::string b = dir.file("b");
  dir.write("b/slurm/jobs.tsv", "1\t42\t43\t0-3\tt\n2\t50\t51\t3\tt\n");
  dir.write("b/slurm/task-42_1.out",
            "slurmstepd: error: *** JOB 44 ON n CANCELLED AT 2026 DUE TO TIME LIMIT ***\n");
  fake_command(dir, "sacct", "echo 'Slurm accounting storage is disabled' >&2; exit 1\n");
  fake_command(dir, "squeue", "case \"$3\" in --jobs=50) echo '50_3|RUNNING';; *) exit 1;; esac\n");
  const auto subs = read_submissions(b);
  TaskStates q = query_states(b, subs, {1, 2, 3}, SlurmTools::from_path(dir.file("bin")));
  EXPECT_EQ(q.sacct_note, "sacct: Slurm accounting storage is disabled");
  EXPECT_EQ(q.by_task.at(1).state, "TIMEOUT");
  EXPECT_EQ(q.by_task.at(1).source, "its output");
  EXPECT_EQ(q.by_task.at(1).job, "42_1");
  EXPECT_EQ(q.by_task.at(2).state, "");         // nothing known
  EXPECT_EQ(q.by_task.at(3).state, "RUNNING");  // the resubmitted task, from the latest job
  EXPECT_EQ(q.by_task.at(3).job, "50_3");

  fake_command(dir, "sacct", "echo '42_2|OUT_OF_MEMORY'; echo '50_3|COMPLETED'\n");
  q = query_states(b, subs, {1, 2, 3}, SlurmTools::from_path(dir.file("bin")));
  EXPECT_EQ(q.by_task.at(2).state, "OUT_OF_MEMORY");
  EXPECT_EQ(q.by_task.at(2).source, "sacct");
  EXPECT_EQ(q.by_task.at(1).state, "TIMEOUT");  // sacct has nothing: the output still tells
  EXPECT_EQ(q.by_task.at(3).state, "COMPLETED");
}

TEST(BenchTask, RunsOneRunIntoItsFolderAndLeavesARecord) {
  TempDir dir("bench_task");
  PlannedRun run{"room_a", "points", Mode::kSequential, 1, {}};
  run.arguments = {"-c", "echo 'mcslam: error: x.png: corrupt' >&2; exit 1"};
  dir.write("runs/room_a/points/sequential-1/old.txt", "from an earlier attempt");
  TaskRecord r = execute_run(dir.str(), run, "/bin/sh", 10, "42_0");
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.error, "exit code 1: mcslam: error: x.png: corrupt");
  EXPECT_FALSE(fs::exists(dir / "runs/room_a/points/sequential-1/old.txt"));
  auto back = read_task_record(task_record_path(dir.str(), run));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->exit_code, 1);
  EXPECT_EQ(back->slurm_job, "42_0");
  EXPECT_GT(back->end_unix, back->start_unix - 1e-3);
  run.arguments = {"-c", "true"};
  EXPECT_TRUE(execute_run(dir.str(), run, "/bin/sh", 10, "").ok());
  dir.write("runs/room_a/points/sequential-1.task.json", "{\"started\": tr");
  back = read_task_record(task_record_path(dir.str(), run));
  ASSERT_TRUE(back);
  EXPECT_FALSE(back->ok());
  EXPECT_TRUE(contains(back->error, "not a task record"));
  EXPECT_FALSE(read_task_record(dir.file("nothing.task.json")));
}

TEST(BenchProcess, CapturesTheOutputOfShortCommands) {
  const CapturedProcess c =
      capture_process("/bin/sh", {"-c", "echo out; echo err >&2; exit 4"}, 10);
  EXPECT_EQ(c.result.exit_code, 4);
  EXPECT_EQ(c.output, "out\nerr\n");
  EXPECT_EQ(find_program("sh", "/nonexistent:/bin"), "/bin/sh");
  EXPECT_EQ(find_program("no-such-program-here", "/bin:/usr/bin"), "");
}

}  // namespace
}  // namespace mcslam::app::bench
