#include "mcslam/app/bench/scoreboard.hpp"

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "mcslam/app/bench/published.hpp"
#include "mcslam/app/bench/report.hpp"
#include "mcslam/app/bench/task.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

nlohmann::json failed_run(const std::string& sequence, const std::string& config,
                          const nlohmann::json& mode, const nlohmann::json& index,
                          const std::string& error) {
  return {{"sequence", sequence},
          {"config", config},
          {"mode", mode},
          {"index", index},
          {"error", error}};
}

nlohmann::json published_json(const SequenceResult& result) {
  nlohmann::json rows = nlohmann::json::array();
  for (const PublishedRow& row : result.published) {
    const auto ours = our_figure(result, row.compares_with);
    const auto online = our_online_figure(result, row.compares_with);
    nlohmann::json values = nlohmann::json::array();
    for (const auto& [method, v] : row.values) values.push_back({method, v});
    rows.push_back({{"table", row.table},
                    {"metric", row.metric},
                    {"source", row.source},
                    {"ours_config", ours ? nlohmann::json(ours->first) : nlohmann::json(nullptr)},
                    {"ours", ours ? nlohmann::json(ours->second) : nlohmann::json(nullptr)},
                    {"ours_online", online ? nlohmann::json(*online) : nlohmann::json(nullptr)},
                    {"values", values}});
  }
  return rows;
}

}  // namespace

Scoreboard::Scoreboard(const BenchSettings& settings) : settings_(settings) {
  for (const Sequence& s : settings_.sequences) states_.push_back(prepare(s));
}

Scoreboard::SequenceState Scoreboard::prepare(const Sequence& sequence) const {
  SequenceState state;
  state.result.sequence = sequence;
  state.boxes = box_source_for(sequence, settings_.model);
  state.result.boxes = state.boxes.describe();
  state.result.published = published_for(sequence.name);
  try {
    const io::RgbdSequence seq = io::RgbdSequence::open(sequence.path);
    std::size_t frames = seq.frames().size();
    if (settings_.max_frames > 0)
      frames = std::min(frames, static_cast<std::size_t>(settings_.max_frames));
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
  for (const Config& c : settings_.configs) {
    ConfigResult cr;
    cr.config = c;
    if (c.boxes && !state.boxes.any())
      cr.skipped = "no boxes for this sequence (give --model, or put a detections.json in it)";
    state.result.configs.push_back(cr);
  }
  state.representatives.resize(settings_.configs.size());
  return state;
}

std::vector<PlannedRun> Scoreboard::plan(const std::string& dir) const {
  std::vector<PlannedRun> runs;
  for (const SequenceState& state : states_) {
    if (state.result.error) continue;
    const auto& configs = state.result.configs;
    std::optional<std::size_t> overlay_config;  // the last configuration run on the sequence
    for (std::size_t ci = 0; ci < configs.size(); ++ci)
      if (!configs[ci].skipped) overlay_config = ci;
    for (std::size_t ci = 0; ci < configs.size(); ++ci) {
      if (configs[ci].skipped) continue;
      for (Mode mode : settings_.modes)
        for (int i = 1; i <= settings_.runs; ++i) {
          PlannedRun run{state.result.sequence.name, configs[ci].config.name, mode, i, {}};
          RunSpec spec{&state.result.sequence, &settings_.configs[ci], mode, i,
                       (fs::path(dir) / run.folder()).string()};
          spec.save_map = mode == settings_.modes.front() && i == 1;
          spec.save_overlays = spec.save_map && settings_.overlays > 0 && overlay_config == ci;
          run.arguments =
              run_arguments(spec, state.boxes, settings_.max_frames, settings_.confidence);
          runs.push_back(std::move(run));
        }
    }
  }
  return runs;
}

std::pair<std::size_t, std::size_t> Scoreboard::locate(const PlannedRun& run) const {
  for (std::size_t si = 0; si < states_.size(); ++si) {
    if (states_[si].result.sequence.name != run.sequence) continue;
    const auto& configs = states_[si].result.configs;
    for (std::size_t ci = 0; ci < configs.size(); ++ci)
      if (configs[ci].config.name == run.config) return {si, ci};
  }
  throw InputError(run.describe() + ": not a run of this bench");
}

std::optional<std::string> Scoreboard::check(const PlannedRun& run) const {
  const auto [si, ci] = locate(run);
  const SequenceResult& r = states_[si].result;
  if (r.error) return "sequence " + run.sequence + " is not run: " + *r.error;
  if (r.configs[ci].skipped)
    return "configuration " + run.config + " is skipped on " + run.sequence + ": " +
           *r.configs[ci].skipped;
  return std::nullopt;
}

const RunRecord& Scoreboard::add(std::size_t k, const PlannedRun& run, const std::string& dir,
                                 const std::string& failure, double wall_s) {
  const auto [si, ci] = locate(run);
  const SequenceState& state = states_[si];
  RunSpec spec{&state.result.sequence, &settings_.configs[ci], run.mode, run.index,
               run_directory(dir, run)};
  Entry entry{si, ci, {}};
  eval::EvalReport report;
  if (failure.empty()) {
    entry.record = score_run(spec, run.folder(), state.groundtruth, &report);
  } else {
    entry.record.sequence = run.sequence;
    entry.record.config = run.config;
    entry.record.mode = run.mode;
    entry.record.index = run.index;
    entry.record.output = run.folder();
    entry.record.error = failure;
  }
  entry.record.wall_s = wall_s;
  if (entry.record.ok) consider_representative(k, entry, spec.output_dir, report);
  return (records_[k] = std::move(entry)).record;
}

void Scoreboard::consider_representative(std::size_t k, const Entry& entry,
                                         const std::string& run_dir,
                                         const eval::EvalReport& report) {
  auto& slot = states_[entry.sequence].representatives[entry.config];
  if (slot && slot->k < k) return;
  Representative rep;
  rep.k = k;
  rep.dir = run_dir;
  rep.folder = fs::path(run_dir).filename().string();
  try {
    rep.estimate = io::read_tum_trajectory(run_dir + "/trajectory.txt");
  } catch (const InputError&) {
  }
  if (entry.record.ate_rmse_m) rep.report = report;
  slot = std::move(rep);
}

int Scoreboard::sequences_not_run() const {
  int n = 0;
  for (const SequenceState& s : states_) n += s.result.error ? 1 : 0;
  return n;
}

std::vector<SequenceResult> Scoreboard::results() const {
  std::vector<SequenceResult> out;
  for (const SequenceState& s : states_) out.push_back(s.result);
  for (const auto& [k, e] : records_) out[e.sequence].configs[e.config].runs.push_back(e.record);
  for (SequenceResult& r : out)
    for (ConfigResult& c : r.configs) summarise(c);
  return out;
}

std::string Scoreboard::write_tables(const std::string& dir, const BenchMeta& meta) const {
  const std::vector<SequenceResult> r = results();
  const std::string md = markdown(meta, r);
  const fs::path out(dir);
  io::write_file_atomic((out / "results.md").string(), md);
  io::write_file_atomic((out / "runs.csv").string(), runs_csv(r));
  io::write_file_atomic((out / "results.json").string(), results_json(meta, r).dump(1) + "\n");
  return md;
}

nlohmann::json Scoreboard::sequence_report(std::size_t si, const SequenceResult& result) const {
  const SequenceState& state = states_[si];
  const auto& configs = settings_.configs;
  nlohmann::json js;
  js["groundtruth"] = state.groundtruth
                          ? groundtruth_json(*state.groundtruth, state.t0 - 0.5, state.t1 + 0.5)
                          : nlohmann::json(nullptr);
  std::optional<std::size_t> map_config;
  for (std::size_t ci = 0; ci < configs.size(); ++ci) {
    const auto& rep = state.representatives[ci];
    nlohmann::json t = rep ? trajectory_json(rep->estimate, rep->report ? &*rep->report : nullptr)
                           : nlohmann::json(nullptr);
    if (rep) t["run"] = rep->folder;
    js["trajectory"].push_back(t);
    if (rep && fs::exists(fs::path(rep->dir) / "map.json")) map_config = ci;
  }
  js["published"] = published_json(result);
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
    js["overlays"] = overlays_json(rep->dir, settings_.overlays);
    break;
  }
  // The occupancy grid of the last configuration that made one (the full system's, listed last).
  js["grid"] = nullptr;
  for (std::size_t ci = configs.size(); ci-- > 0;) {
    const auto& rep = state.representatives[ci];
    if (!rep) continue;
    nlohmann::json grid = grid_json(rep->dir);
    if (grid.is_null()) continue;
    grid["config"] = configs[ci].name;
    grid["run"] = rep->folder;
    js["grid"] = std::move(grid);
    break;
  }
  return js;
}

nlohmann::json Scoreboard::report_data(const BenchMeta& meta, const std::string& markdown) const {
  const std::vector<SequenceResult> results = this->results();
  nlohmann::json data = results_json(meta, results);
  data["format"] = "mcslam-bench-report";
  data["markdown"] = markdown;
  data["configs"] = nlohmann::json::array();
  for (const Config& c : settings_.configs)
    data["configs"].push_back(
        {{"name", c.name}, {"label", c.label}, {"description", c.description}});
  data["failed_runs"] = nlohmann::json::array();
  for (std::size_t si = 0; si < states_.size(); ++si) {
    if (const auto& error = states_[si].result.error)
      data["failed_runs"].push_back(
          failed_run(states_[si].result.sequence.name, "all", nullptr, nullptr, *error));
    for (const ConfigResult& c : results[si].configs)
      for (const RunRecord& r : c.runs)
        if (!r.ok)
          data["failed_runs"].push_back(
              failed_run(r.sequence, r.config, to_string(r.mode), r.index, r.error));
    nlohmann::json part = sequence_report(si, results[si]);
    nlohmann::json& js = data["sequences"][si];
    for (std::size_t ci = 0; ci < settings_.configs.size(); ++ci)
      js["results"][ci]["trajectory"] = part["trajectory"][ci];
    for (const char* key : {"groundtruth", "published", "map", "overlays", "grid"})
      js[key] = part[key];
  }
  return data;
}

std::string Scoreboard::write_report(const std::string& dir, const BenchMeta& meta,
                                     const std::string& markdown, const std::string& assets,
                                     std::string& warning) const {
  const fs::path bundle_path = fs::path(assets) / "report.js";
  std::ifstream bundle(bundle_path, std::ios::binary);
  if (!bundle) {
    warning = "report.html not written: the report's scripts " + bundle_path.string() +
              " were not built (run scripts/install-deps.sh, then rebuild)";
    return "";
  }
  std::ostringstream js;
  js << bundle.rdbuf();
  const std::string path = (fs::path(dir) / "report.html").string();
  io::write_file_atomic(path, report_html(report_data(meta, markdown), js.str()));
  return path;
}

}  // namespace mcslam::app::bench
