#include "mcslam/app/bench.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <thread>

#include "mcslam/app/bench/plan.hpp"
#include "mcslam/app/bench/process.hpp"
#include "mcslam/app/bench/published.hpp"
#include "mcslam/app/bench/report.hpp"
#include "mcslam/app/bench/results.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::app {
namespace {

namespace fs = std::filesystem;
using namespace bench;

struct Plan {
  std::vector<Sequence> sequences;
  std::vector<Config> configs;
  std::vector<Mode> modes;
};

Plan make_plan(const BenchRequest& request) {
  if (request.data_roots.empty()) throw InputError("give at least one DATA_ROOT folder");
  if (request.runs < 1) throw InputError("--runs: must be at least 1");
  if (request.max_frames < 0) throw InputError("--max-frames: must not be negative");
  if (request.overlays < 0) throw InputError("--overlays: must not be negative");
  if (request.model) {
    std::error_code ec;
    if (!fs::is_regular_file(*request.model, ec))
      throw InputError(file_error(*request.model, "no such model file (--model)"));
  }
  if (request.confidence && !(*request.confidence > 0 && *request.confidence < 1))
    throw InputError("--confidence: must be in (0, 1)");
  Plan plan;
  plan.configs = select_configs(request.configs);
  plan.modes = select_modes(request.modes);
  plan.sequences = filter_sequences(discover_sequences(request.data_roots, request.output_dir),
                                    request.sequences);
  if (plan.sequences.empty()) {
    std::string roots;
    for (const auto& r : request.data_roots) roots += (roots.empty() ? "" : ", ") + r;
    throw InputError(roots +
                     ": no TUM-layout sequence (a folder with rgb.txt and depth.txt) in it");
  }
  return plan;
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

std::string host_name() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "unknown";
  return name;
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

/// The run whose trajectory (and map, overlays) the report shows for one configuration.
struct Representative {
  std::string dir;
  std::string folder;
  Trajectory estimate;
  std::optional<eval::EvalReport> report;
};

/// Everything the bench knows about one sequence while it runs.
struct SequenceState {
  SequenceResult result;
  BoxSource boxes;
  std::optional<Trajectory> groundtruth;
  double t0 = 1, t1 = 0;  // time span of the frames run (t0 > t1: unknown)
  std::vector<std::optional<Representative>> representatives;  // per configuration
};

SequenceState prepare_sequence(const Sequence& sequence, const std::vector<Config>& configs,
                               const BenchRequest& request) {
  SequenceState state;
  state.result.sequence = sequence;
  state.boxes = box_source_for(sequence, request.model);
  state.result.boxes = state.boxes.describe();
  state.result.published = published_for(sequence.name);
  try {
    const io::RgbdSequence seq = io::RgbdSequence::open(sequence.path);
    std::size_t frames = seq.frames().size();
    if (request.max_frames > 0)
      frames = std::min(frames, static_cast<std::size_t>(request.max_frames));
    state.result.frames = static_cast<int>(frames);
    if (frames > 0) {
      state.t0 = seq.frames().front().rgb_timestamp;
      state.t1 = seq.frames()[frames - 1].rgb_timestamp;
    }
    if (const auto gt = seq.groundtruth_path()) {
      try {
        state.groundtruth = io::read_tum_trajectory(*gt);
        if (sequence.kind == DatasetKind::kBonn)
          state.groundtruth = eval::bonn_marker_to_camera(*state.groundtruth);
      } catch (const InputError& e) {
        state.result.groundtruth_note = std::string("ground truth not used: ") + e.what();
      }
    } else {
      state.result.groundtruth_note = "no groundtruth.txt, so no ATE or RPE";
    }
  } catch (const InputError& e) {
    // `mcslam run` would fail the same way: the sequence is reported once and not run.
    state.result.error = std::string("sequence unreadable: ") + e.what();
  }
  for (const Config& c : configs) {
    ConfigResult cr;
    cr.config = c;
    if (c.boxes && !state.boxes.any())
      cr.skipped = "no boxes for this sequence (give --model, or put a detections.json in it)";
    state.result.configs.push_back(cr);
  }
  state.representatives.resize(configs.size());
  return state;
}

struct Job {
  std::size_t sequence = 0, config = 0;
  Mode mode = Mode::kSequential;
  int index = 1;
};

void write_tables(const fs::path& out, const BenchMeta& meta,
                  const std::vector<SequenceState>& states, std::string* markdown_out) {
  std::vector<SequenceResult> results;
  for (const SequenceState& s : states) results.push_back(s.result);
  for (SequenceResult& r : results)
    for (ConfigResult& c : r.configs) summarise(c);
  const std::string md = markdown(meta, results);
  io::write_file_atomic((out / "results.md").string(), md);
  io::write_file_atomic((out / "runs.csv").string(), runs_csv(results));
  io::write_file_atomic((out / "results.json").string(),
                        results_json(meta, results).dump(1) + "\n");
  if (markdown_out) *markdown_out = md;
}

nlohmann::json report_data(const BenchMeta& meta, const std::vector<SequenceState>& states,
                           const std::vector<Config>& configs, const std::string& markdown_text,
                           int overlays) {
  std::vector<SequenceResult> results;
  for (const SequenceState& s : states) results.push_back(s.result);
  for (SequenceResult& r : results)
    for (ConfigResult& c : r.configs) summarise(c);
  nlohmann::json data = results_json(meta, results);
  data["format"] = "mcslam-bench-report";
  data["markdown"] = markdown_text;
  data["configs"] = nlohmann::json::array();
  for (const Config& c : configs)
    data["configs"].push_back(
        {{"name", c.name}, {"label", c.label}, {"description", c.description}});
  data["failed_runs"] = nlohmann::json::array();
  for (std::size_t si = 0; si < states.size(); ++si) {
    const SequenceState& state = states[si];
    nlohmann::json& js = data["sequences"][si];
    if (state.result.error)
      data["failed_runs"].push_back({{"sequence", state.result.sequence.name},
                                     {"config", "all"},
                                     {"mode", nullptr},
                                     {"index", nullptr},
                                     {"error", *state.result.error}});
    for (const ConfigResult& c : results[si].configs)
      for (const RunRecord& r : c.runs)
        if (!r.ok)
          data["failed_runs"].push_back({{"sequence", r.sequence},
                                         {"config", r.config},
                                         {"mode", to_string(r.mode)},
                                         {"index", r.index},
                                         {"error", r.error}});
    js["groundtruth"] = state.groundtruth
                            ? groundtruth_json(*state.groundtruth, state.t0 - 0.5, state.t1 + 0.5)
                            : nlohmann::json(nullptr);
    std::optional<std::size_t> map_config;
    for (std::size_t ci = 0; ci < configs.size(); ++ci) {
      const auto& rep = state.representatives[ci];
      js["results"][ci]["trajectory"] =
          rep ? trajectory_json(rep->estimate, rep->report ? &*rep->report : nullptr)
              : nlohmann::json(nullptr);
      if (rep) js["results"][ci]["trajectory"]["run"] = rep->folder;
      if (rep && fs::exists(fs::path(rep->dir) / "map.json")) map_config = ci;
    }
    js["published"] = nlohmann::json::array();
    for (const PublishedRow& row : state.result.published) {
      const auto ours = our_figure(results[si], row.compares_with);
      nlohmann::json values = nlohmann::json::array();
      for (const auto& [method, v] : row.values) values.push_back({method, v});
      js["published"].push_back(
          {{"table", row.table},
           {"metric", row.metric},
           {"source", row.source},
           {"ours_config", ours ? nlohmann::json(ours->first) : nlohmann::json(nullptr)},
           {"ours", ours ? nlohmann::json(ours->second) : nlohmann::json(nullptr)},
           {"values", values}});
    }
    js["map"] = nullptr;
    js["overlays"] = nlohmann::json::array();
    if (map_config) {
      const Representative& rep = *state.representatives[*map_config];
      try {
        nlohmann::json m = map_json((fs::path(rep.dir) / "map.json").string());
        m["config"] = configs[*map_config].name;
        m["run"] = rep.folder;
        js["map"] = m;
      } catch (const InputError& e) {
        std::cerr << "mcslam bench: warning: no map in the report: " << e.what() << "\n";
      }
    }
    for (std::size_t ci = configs.size(); ci-- > 0;) {
      const auto& rep = state.representatives[ci];
      if (!rep || !fs::exists(fs::path(rep->dir) / "overlays")) continue;
      js["overlays"] = overlays_json(rep->dir, overlays);
      break;
    }
  }
  return data;
}

}  // namespace

std::string list_sequences(const BenchRequest& request) {
  const Plan plan = make_plan(request);
  std::ostringstream s;
  for (const Sequence& seq : plan.sequences)
    s << seq.name << "  " << to_string(seq.kind)
      << "  boxes: " << box_source_for(seq, request.model).describe() << "  " << seq.path << "\n";
  return s.str();
}

BenchOutcome run_bench(const BenchRequest& request) {
  const Plan plan = make_plan(request);
  const fs::path out(request.output_dir);
  io::ensure_directory(out.string());
  const std::string exe = request.executable.empty() ? current_executable() : request.executable;
  if (exe.empty()) throw InputError("cannot find the mcslam executable to run (/proc/self/exe)");

  BenchMeta meta;
  meta.created_utc = utc_now();
  meta.command = request.command_line;
  meta.hostname = host_name();
  meta.cpus = static_cast<int>(std::thread::hardware_concurrency());
  meta.runs_per_mode = request.runs;
  meta.modes = plan.modes;

  std::vector<SequenceState> states;
  for (const Sequence& s : plan.sequences)
    states.push_back(prepare_sequence(s, plan.configs, request));

  std::vector<Job> jobs;
  for (std::size_t si = 0; si < states.size(); ++si)
    for (std::size_t ci = 0; ci < plan.configs.size(); ++ci) {
      if (states[si].result.configs[ci].skipped || states[si].result.error) continue;
      for (Mode mode : plan.modes)
        for (int i = 1; i <= request.runs; ++i) jobs.push_back({si, ci, mode, i});
    }
  // The configuration whose first run saves overlays: the last one run on the sequence.
  std::vector<std::optional<std::size_t>> overlay_config(states.size());
  for (const Job& j : jobs) overlay_config[j.sequence] = j.config;

  if (request.progress)
    std::cerr << "mcslam bench: " << states.size() << " sequence(s), " << plan.configs.size()
              << " configuration(s), " << jobs.size() << " runs; results in " << out.string()
              << "\n";
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  BenchOutcome outcome;
  for (const SequenceState& s : states)
    if (s.result.error) {
      ++outcome.sequences_not_run;
      if (request.progress)
        std::cerr << "mcslam bench: " << s.result.sequence.name << " not run: " << *s.result.error
                  << "\n";
    }
  const int width = static_cast<int>(std::to_string(jobs.size()).size());
  for (std::size_t k = 0; k < jobs.size(); ++k) {
    const Job& job = jobs[k];
    SequenceState& state = states[job.sequence];
    const Config& config = plan.configs[job.config];
    const bool first = job.mode == plan.modes.front() && job.index == 1;
    RunSpec spec;
    spec.sequence = &state.result.sequence;
    spec.config = &config;
    spec.mode = job.mode;
    spec.index = job.index;
    const std::string folder = run_folder_name(job.mode, job.index);
    const fs::path relative = fs::path("runs") / spec.sequence->name / config.name / folder;
    spec.output_dir = (out / relative).string();
    spec.save_map = first;
    spec.save_overlays =
        first && request.overlays > 0 && overlay_config[job.sequence] == job.config;
    const std::string log = spec.output_dir + ".log";
    std::error_code ec;
    fs::remove_all(spec.output_dir, ec);
    fs::remove(log, ec);
    io::ensure_directory(spec.output_dir);

    if (request.progress) {
      std::fprintf(stderr, "[%*zu/%zu] %s · %s · %s %d/%d ... ", width, k + 1, jobs.size(),
                   spec.sequence->name.c_str(), config.label.c_str(), to_string(job.mode),
                   job.index, request.runs);
      std::fflush(stderr);
    }
    const ProcessResult process =
        run_process(exe, run_arguments(spec, state.boxes, request.max_frames, request.confidence),
                    log, request.timeout_s);
    eval::EvalReport report;
    RunRecord record;
    if (process.ok()) {
      record = score_run(spec, relative.string(), state.groundtruth, &report);
    } else {
      record.sequence = spec.sequence->name;
      record.config = config.name;
      record.mode = job.mode;
      record.index = job.index;
      record.output = relative.string();
      record.error = failure_text(process, log, request.timeout_s);
    }
    record.wall_s = process.wall_s;
    ++outcome.runs;
    if (!record.ok) ++outcome.failed;
    auto& representative = state.representatives[job.config];
    if (record.ok && !representative) {
      Representative rep;
      rep.dir = spec.output_dir;
      rep.folder = folder;
      try {
        rep.estimate = io::read_tum_trajectory(spec.output_dir + "/trajectory.txt");
      } catch (const InputError&) {
      }
      if (record.ate_rmse_m) rep.report = report;
      representative = std::move(rep);
    }
    if (request.progress) {
      std::ostringstream line;
      if (!record.ok) {
        line << "FAILED: " << record.error;
      } else {
        line.setf(std::ios::fixed);
        if (record.ate_rmse_m)
          line << "ATE " << std::setprecision(4) << *record.ate_rmse_m << " m, ";
        if (record.tracked_ratio)
          line << "tracked " << std::setprecision(0) << 100 * *record.tracked_ratio << " %, ";
        if (record.fps) line << std::setprecision(1) << *record.fps << " fps, ";
        line << minutes(record.wall_s);
      }
      const double done = elapsed();
      const double left = done / (k + 1) * (jobs.size() - k - 1);
      std::cerr << line.str() << "  [" << minutes(done) << " elapsed"
                << (k + 1 < jobs.size() ? ", about " + minutes(left) + " left" : std::string())
                << "]\n";
    }
    state.result.configs[job.config].runs.push_back(std::move(record));
    meta.wall_time_s = elapsed();
    write_tables(out, meta, states, nullptr);
  }

  meta.wall_time_s = elapsed();
  write_tables(out, meta, states, &outcome.markdown);

  const fs::path assets = request.report_assets.empty() ? fs::path(exe).parent_path() / "report"
                                                        : fs::path(request.report_assets);
  const fs::path bundle_path = assets / "report.js";
  std::ifstream bundle(bundle_path, std::ios::binary);
  if (!bundle) {
    outcome.report_warning = "report.html not written: the report's scripts " +
                             bundle_path.string() +
                             " were not built (run scripts/install-deps.sh, then rebuild)";
  } else {
    std::ostringstream js;
    js << bundle.rdbuf();
    const nlohmann::json data =
        report_data(meta, states, plan.configs, outcome.markdown, request.overlays);
    outcome.report_path = (out / "report.html").string();
    io::write_file_atomic(outcome.report_path, report_html(data, js.str()));
  }
  return outcome;
}

}  // namespace mcslam::app
