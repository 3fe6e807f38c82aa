#include "mcslam/app/bench/results.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file_error(path.string(), "missing: the run wrote no results"));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Stage names from the timings.csv header, in pipeline order.
std::vector<std::string> stage_order(const fs::path& timings) {
  std::ifstream in(timings);
  std::string header;
  std::getline(in, header);
  std::vector<std::string> names;
  std::stringstream columns(header);
  for (std::string c; std::getline(columns, c, ',');) {
    if (c.size() > 3 && c.compare(c.size() - 3, 3, "_ms") == 0 && c != "total_ms")
      names.push_back(c.substr(0, c.size() - 3));
  }
  return names;
}

std::optional<double> number_at(const nlohmann::json& j, std::initializer_list<const char*> path) {
  const nlohmann::json* node = &j;
  for (const char* key : path) {
    if (!node->is_object() || !node->contains(key)) return std::nullopt;
    node = &(*node)[key];
  }
  if (!node->is_number()) return std::nullopt;
  return node->get<double>();
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

/// "0.0105 (0.0103–0.0111)", "0.0105" when all runs agree at this precision, "–" for none;
/// "(2 of 3 runs)" when some runs gave no figure.
std::string cell(const std::optional<Spread>& s, int digits, int expected_runs) {
  if (!s) return "–";
  std::string text = fixed(s->median, digits);
  if (fixed(s->min, digits) != fixed(s->max, digits))
    text += " (" + fixed(s->min, digits) + "–" + fixed(s->max, digits) + ")";
  if (s->n < expected_runs)
    text += " [" + std::to_string(s->n) + " of " + std::to_string(expected_runs) + " runs]";
  return text;
}

std::string percent_cell(const std::optional<Spread>& s, int expected_runs) {
  if (!s) return "–";
  Spread p = *s;
  p.median *= 100;
  p.min *= 100;
  p.max *= 100;
  return cell(p, 1, expected_runs) + " %";
}

std::string escape_cell(std::string s) {
  for (std::size_t at = 0; (at = s.find('|', at)) != std::string::npos; at += 2)
    s.replace(at, 1, "\\|");
  std::replace(s.begin(), s.end(), '\n', ' ');
  return s;
}

int runs_in_mode(const ConfigResult& c, Mode mode) {
  return static_cast<int>(std::count_if(c.runs.begin(), c.runs.end(),
                                        [&](const RunRecord& r) { return r.mode == mode; }));
}

bool has_mode(const ConfigResult& c, Mode mode) { return runs_in_mode(c, mode) > 0; }

/// Runs that give accuracy figures: sequential ones, or all when there are none.
int accuracy_runs(const ConfigResult& c) {
  return has_mode(c, Mode::kSequential) ? runs_in_mode(c, Mode::kSequential)
                                        : static_cast<int>(c.runs.size());
}
int speed_runs(const ConfigResult& c) {
  return has_mode(c, Mode::kThreaded) ? runs_in_mode(c, Mode::kThreaded)
                                      : static_cast<int>(c.runs.size());
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string csv_number(const std::optional<double>& v) {
  if (!v) return "";
  std::ostringstream s;
  s << std::setprecision(9) << *v;
  return s.str();
}

nlohmann::json optional_number(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

nlohmann::json optional_text(const std::optional<std::string>& s) {
  return s ? nlohmann::json(*s) : nlohmann::json(nullptr);
}

/// [[name, ms], ...]: an array keeps the pipeline order.
nlohmann::json stages_json(const std::vector<std::pair<std::string, double>>& stages) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& [name, ms] : stages) j.push_back({name, ms});
  return j;
}

}  // namespace

RunRecord score_run(const RunSpec& spec, const std::string& relative_output,
                    const std::optional<Trajectory>& groundtruth, eval::EvalReport* eval_out) {
  RunRecord r;
  r.sequence = spec.sequence->name;
  r.config = spec.config->name;
  r.mode = spec.mode;
  r.index = spec.index;
  r.output = relative_output;
  const fs::path dir(spec.output_dir);
  try {
    const fs::path summary_path = dir / "summary.json";
    nlohmann::json summary;
    try {
      summary = nlohmann::json::parse(read_text(summary_path));
    } catch (const nlohmann::json::exception& e) {
      throw InputError(file_error(summary_path.string(), std::string("not JSON: ") + e.what()));
    }
    r.frames = static_cast<int>(number_at(summary, {"frames"}).value_or(0));
    r.tracked_ratio = number_at(summary, {"tracked_ratio"});
    r.fps = number_at(summary, {"frames_per_second"});
    r.tracking_ms = number_at(summary, {"stages", "tracking_total", "median_ms"});
    r.dynamics_ms = number_at(summary, {"stages", "dynamics", "mean_ms"});
    r.keyframes = number_at(summary, {"keyframes_in_map"});
    r.loops_verified = number_at(summary, {"loops", "detected"});
    r.loops_accepted = number_at(summary, {"loops", "accepted"});
    if (number_at(summary, {"loops", "keyframes_checked"}).value_or(0) > 0)
      r.loop_detection_ms = number_at(summary, {"loops", "detection_median_ms"});
    r.relocalisations = number_at(summary, {"relocalisations"});
    r.unsmoothed_ate_rmse_m = number_at(summary, {"trajectory_smoothing", "unsmoothed_ate_rmse_m"});
    r.online_ate_rmse_m = number_at(summary, {"online_ate_rmse_m"});
    r.processed_ratio = number_at(summary, {"realtime", "processed_ratio"});
    r.latency_ms = number_at(summary, {"realtime", "latency_median_ms"});
    r.detector_rate_hz = number_at(summary, {"dynamics", "detector_rate_hz"});
    if (number_at(summary, {"relocalisation", "attempts"}).value_or(0) > 0)
      r.relocalisation_query_ms = number_at(summary, {"relocalisation", "query_median_ms"});
    std::vector<std::string> order = {"image_load"};
    for (const std::string& s : stage_order(dir / "timings.csv"))
      if (s != "image_load") order.push_back(s);
    for (const std::string& name : order)
      if (const auto ms = number_at(summary, {"stages", name.c_str(), "median_ms"}))
        r.stages_ms.emplace_back(name, *ms);
    const bool tracked_none = number_at(summary, {"tracked_frames"}).value_or(1) == 0;
    if (tracked_none) r.note = "no pose was tracked, so there is no ATE";
    if (groundtruth && !tracked_none) {
      const Trajectory estimate = io::read_tum_trajectory((dir / "trajectory.txt").string());
      if (estimate.empty()) {
        r.note = "no pose was tracked, so there is no ATE";
      } else {
        try {
          const eval::EvalReport report = eval::evaluate(*groundtruth, estimate);
          r.ate_rmse_m = report.ate.translation.rmse;
          if (report.rpe_time.translation.count > 0) {
            r.rpe_trans_m = report.rpe_time.translation.rmse;
            r.rpe_rot_deg = report.rpe_time.rotation.rmse * 180.0 / M_PI;
          }
          if (eval_out) *eval_out = report;
        } catch (const InputError& e) {
          r.note = std::string("not scored: ") + e.what();
        }
      }
    }
    r.ok = true;
  } catch (const InputError& e) {
    r.ok = false;
    r.error = e.what();
  }
  return r;
}

std::optional<Spread> spread(const std::vector<double>& values) {
  if (values.empty()) return std::nullopt;
  Spread s;
  s.median = median_of(values);
  s.min = *std::min_element(values.begin(), values.end());
  s.max = *std::max_element(values.begin(), values.end());
  s.n = static_cast<int>(values.size());
  return s;
}

void summarise(ConfigResult& c) {
  const bool sequential = has_mode(c, Mode::kSequential);
  const bool threaded = has_mode(c, Mode::kThreaded);
  const bool offline = sequential || threaded;
  std::vector<const RunRecord*> accuracy, speed, threaded_runs, realtime_runs;
  for (const RunRecord& r : c.runs) {
    if (!r.ok) continue;
    // Real-time runs give accuracy and speed figures of their own, and the main ones only when
    // there is nothing else.
    if (r.mode == Mode::kRealtime) realtime_runs.push_back(&r);
    if (offline && r.mode == Mode::kRealtime) continue;
    if (!sequential || r.mode == Mode::kSequential) accuracy.push_back(&r);
    if (!threaded || r.mode == Mode::kThreaded) speed.push_back(&r);
    if (r.mode == Mode::kThreaded) threaded_runs.push_back(&r);
  }
  auto collect = [](const std::vector<const RunRecord*>& runs,
                    std::optional<double> RunRecord::*field) {
    std::vector<double> v;
    for (const RunRecord* r : runs)
      if (r->*field) v.push_back(*(r->*field));
    return spread(v);
  };
  c.ate = collect(accuracy, &RunRecord::ate_rmse_m);
  c.ate_threaded = collect(threaded_runs, &RunRecord::ate_rmse_m);
  c.ate_unsmoothed = collect(accuracy, &RunRecord::unsmoothed_ate_rmse_m);
  c.ate_online = collect(accuracy, &RunRecord::online_ate_rmse_m);
  c.rpe_trans = collect(accuracy, &RunRecord::rpe_trans_m);
  c.rpe_rot_deg = collect(accuracy, &RunRecord::rpe_rot_deg);
  c.tracked = collect(accuracy, &RunRecord::tracked_ratio);
  c.fps = collect(speed, &RunRecord::fps);
  c.tracking_ms = collect(speed, &RunRecord::tracking_ms);
  if (const auto d = collect(speed, &RunRecord::dynamics_ms)) c.dynamics_ms = d->median;
  std::vector<const RunRecord*> all;
  for (const RunRecord& r : c.runs)
    if (r.ok) all.push_back(&r);
  c.keyframes = collect(all, &RunRecord::keyframes);
  c.loops_verified = collect(all, &RunRecord::loops_verified);
  c.loops_accepted = collect(all, &RunRecord::loops_accepted);
  c.loop_detection_ms = collect(all, &RunRecord::loop_detection_ms);
  c.relocalisations = collect(all, &RunRecord::relocalisations);
  c.relocalisation_query_ms = collect(all, &RunRecord::relocalisation_query_ms);
  c.ate_realtime = collect(realtime_runs, &RunRecord::ate_rmse_m);
  c.processed = collect(realtime_runs, &RunRecord::processed_ratio);
  c.latency_ms = collect(realtime_runs, &RunRecord::latency_ms);
  c.detector_rate_hz = collect(realtime_runs, &RunRecord::detector_rate_hz);
  c.fps_realtime = collect(realtime_runs, &RunRecord::fps);
  const auto stage_medians = [](const std::vector<const RunRecord*>& runs) {
    std::vector<std::pair<std::string, double>> out;
    if (runs.empty()) return out;
    for (const auto& [name, ms] : runs.front()->stages_ms) {
      std::vector<double> v;
      for (const RunRecord* r : runs)
        for (const auto& [n, x] : r->stages_ms)
          if (n == name) v.push_back(x);
      out.emplace_back(name, median_of(v));
    }
    return out;
  };
  c.stages_ms = stage_medians(speed);
  c.stages_ms_realtime = stage_medians(realtime_runs);
}

std::optional<std::pair<std::string, double>> our_figure(const SequenceResult& sequence,
                                                         Metric metric) {
  for (auto it = sequence.configs.rbegin(); it != sequence.configs.rend(); ++it) {
    std::optional<double> v;
    switch (metric) {
      case Metric::kAteRmse:
        if (it->ate_unsmoothed)
          v = it->ate_unsmoothed->median;
        else if (it->ate)
          v = it->ate->median;  // no smoothing was applied: the same poses
        break;
      case Metric::kRpeTransRmse:
        if (it->rpe_trans) v = it->rpe_trans->median;
        break;
      case Metric::kRpeRotRmseRad:
        if (it->rpe_rot_deg) v = it->rpe_rot_deg->median * M_PI / 180.0;
        break;
      case Metric::kDynamicsTimeS:
        if (it->dynamics_ms && it->config.boxes) v = *it->dynamics_ms / 1000.0;
        break;
    }
    if (v) return std::make_pair(it->config.label, *v);
  }
  return std::nullopt;
}

std::optional<double> our_online_figure(const SequenceResult& sequence, Metric metric) {
  if (metric != Metric::kAteRmse) return std::nullopt;
  const auto chosen = our_figure(sequence, metric);
  if (!chosen) return std::nullopt;
  for (auto it = sequence.configs.rbegin(); it != sequence.configs.rend(); ++it)
    if (it->config.label == chosen->first)
      return it->ate_online ? std::optional<double>(it->ate_online->median) : std::nullopt;
  return std::nullopt;
}

namespace {

/// "sequential, threaded and realtime".
std::string mode_names(const std::vector<Mode>& modes) {
  std::string names;
  for (std::size_t i = 0; i < modes.size(); ++i)
    names +=
        (i == 0 ? "" : (i + 1 == modes.size() ? " and " : ", ")) + std::string(to_string(modes[i]));
  return names;
}

/// The title, the bench's figures and how to read the tables.
void markdown_header(std::ostream& md, const BenchMeta& meta, bool sequential, bool threaded) {
  md << "# mcslam bench\n\n";
  md << meta.created_utc << " · `" << meta.command << "` · " << meta.hostname << ", " << meta.cpus
     << " CPUs · " << meta.runs_per_mode << " run(s) per mode (" << mode_names(meta.modes)
     << ") · wall time " << fixed(meta.wall_time_s / 60.0, 1) << " min"
     << (meta.executor.empty() ? "" : " · " + meta.executor) << "\n\n";
  md << "ATE and RPE (over 1 s) are scored with mcslam's eval code on the whole trajectory (every "
        "frame) of the "
     << (sequential ? "sequential runs, whose mapping is inline and deterministic"
                    : "threaded runs")
     << "; frames per second and times come from the "
     << (threaded ? "threaded runs (the default mode)" : "sequential runs (mapping inline)")
     << ". Medians over runs, with (min–max) where the runs differ. Tracked: share of frames "
        "with a tracked pose. ATE is that of trajectory.txt, whose positions each run smooths "
        "with a motion prior; unsmoothed: the same poses before (the run's summary.json).\n";
}

/// Accuracy and speed per configuration; the failed runs are added to `failed`.
void accuracy_table(std::ostream& md, const SequenceResult& s,
                    std::vector<const RunRecord*>& failed) {
  md << "| configuration | ATE RMSE (m) | unsmoothed (m) | ATE threaded (m) | RPE trans. 1 s (m) "
        "| RPE rot. 1 s (°) | tracked | fps | tracking (ms) |\n";
  md << "|---|---|---|---|---|---|---|---|---|\n";
  for (const ConfigResult& c : s.configs) {
    md << "| " << c.config.label;
    if (c.skipped) {
      md << " | skipped: " << escape_cell(*c.skipped) << " | | | | | | | |\n";
      continue;
    }
    const int acc = accuracy_runs(c), spd = speed_runs(c);
    md << " | " << cell(c.ate, 4, acc) << " | " << cell(c.ate_unsmoothed, 4, acc) << " | "
       << cell(c.ate_threaded, 4, runs_in_mode(c, Mode::kThreaded)) << " | "
       << cell(c.rpe_trans, 4, acc) << " | " << cell(c.rpe_rot_deg, 3, acc) << " | "
       << percent_cell(c.tracked, acc) << " | " << cell(c.fps, 1, spd) << " | "
       << cell(c.tracking_ms, 1, spd) << " |\n";
    for (const RunRecord& r : c.runs)
      if (!r.ok) failed.push_back(&r);
  }
}

/// Place recognition: loops and relocalisations.
void place_table(std::ostream& md, const SequenceResult& s) {
  md << "\nPlace recognition (all runs):\n\n| configuration | keyframes | loops verified | "
        "loops accepted | loop detection per keyframe (ms) | relocalisations | relocalisation "
        "query (ms) |\n|---|---|---|---|---|---|---|\n";
  for (const ConfigResult& c : s.configs) {
    if (c.skipped) continue;
    const int n = static_cast<int>(c.runs.size());
    md << "| " << c.config.label << " | " << cell(c.keyframes, 0, n) << " | "
       << cell(c.loops_verified, 0, n) << " | " << cell(c.loops_accepted, 0, n) << " | "
       << cell(c.loop_detection_ms, 2, n) << " | " << cell(c.relocalisations, 0, n) << " | "
       << cell(c.relocalisation_query_ms, 2, n) << " |\n";
  }
}

/// Live camera: frames delivered at their timestamps (--realtime).
void realtime_table(std::ostream& md, const SequenceResult& s) {
  md << "\nReal time (`--realtime`: frames delivered at their timestamps, the newest wins; ATE "
        "on the frames processed):\n\n| configuration | ATE RMSE (m) | frames processed | "
        "latency median (ms) | fps | detector passes/s |\n|---|---|---|---|---|---|\n";
  for (const ConfigResult& c : s.configs) {
    if (c.skipped || !has_mode(c, Mode::kRealtime)) continue;
    const int n = runs_in_mode(c, Mode::kRealtime);
    md << "| " << c.config.label << " | " << cell(c.ate_realtime, 4, n) << " | "
       << percent_cell(c.processed, n) << " | " << cell(c.latency_ms, 1, n) << " | "
       << cell(c.fps_realtime, 1, n) << " | "
       << (c.config.boxes ? cell(c.detector_rate_hz, 1, n) : std::string("–")) << " |\n";
  }
}

using StageList = std::vector<std::pair<std::string, double>>;

/// Per-stage medians: the stages of the configuration with the most, in its pipeline order,
/// then any others.
void stage_table(std::ostream& md, const SequenceResult& s, StageList ConfigResult::*field,
                 const std::string& runs) {
  std::vector<const ConfigResult*> by_stages;
  for (const ConfigResult& c : s.configs) by_stages.push_back(&c);
  std::stable_sort(by_stages.begin(), by_stages.end(), [&](const auto* a, const auto* b) {
    return (a->*field).size() > (b->*field).size();
  });
  std::vector<std::string> stages;
  for (const ConfigResult* c : by_stages)
    for (const auto& [name, ms] : c->*field)
      if (std::find(stages.begin(), stages.end(), name) == stages.end()) stages.push_back(name);
  if (stages.empty()) return;
  md << "\nPer-stage median (ms), " << runs << " runs:\n\n| configuration |";
  for (const auto& name : stages) md << ' ' << name << " |";
  md << "\n|---|";
  for (std::size_t i = 0; i < stages.size(); ++i) md << "---|";
  md << "\n";
  for (const ConfigResult& c : s.configs) {
    if (c.skipped || (c.*field).empty()) continue;
    md << "| " << c.config.label << " |";
    for (const auto& name : stages) {
      const auto it = std::find_if((c.*field).begin(), (c.*field).end(),
                                   [&](const auto& p) { return p.first == name; });
      md << ' ' << (it == (c.*field).end() ? std::string("–") : fixed(it->second, 1)) << " |";
    }
    md << "\n";
  }
}

/// Published figures of other systems beside ours.
void published_table(std::ostream& md, const SequenceResult& s) {
  std::vector<std::string> methods;
  for (const PublishedRow& row : s.published)
    for (const auto& [method, v] : row.values)
      if (std::find(methods.begin(), methods.end(), method) == methods.end())
        methods.push_back(method);
  md << "\nPublished figures beside ours (mcslam: this machine, the most complete "
        "configuration that gave the figure; its ATE is that of the unsmoothed poses, as "
        "other systems publish theirs, and 'mcslam online' that of the poses given at the "
        "time):\n\n| figure | mcslam | mcslam online |";
  for (const auto& m : methods) md << ' ' << m << " |";
  md << " source |\n|---|---|---|";
  for (std::size_t i = 0; i < methods.size(); ++i) md << "---|";
  md << "---|\n";
  for (const PublishedRow& row : s.published) {
    const auto ours = our_figure(s, row.compares_with);
    const auto online = our_online_figure(s, row.compares_with);
    md << "| " << row.metric << " | "
       << (ours ? fixed(ours->second, 4) + " (" + ours->first + ")" : std::string("–")) << " | "
       << (online ? fixed(*online, 4) : std::string("–")) << " |";
    for (const auto& m : methods) {
      const auto it = std::find_if(row.values.begin(), row.values.end(),
                                   [&](const auto& p) { return p.first == m; });
      md << ' ' << (it == row.values.end() ? std::string("–") : fixed(it->second, 4)) << " |";
    }
    md << ' ' << escape_cell(row.source) << " |\n";
  }
}

/// One sequence's section: its header line and its tables.
void sequence_section(std::ostream& md, const SequenceResult& s, bool sequential, bool threaded,
                      std::vector<const RunRecord*>& failed) {
  md << "\n## " << s.sequence.name << "\n\n";
  md << to_string(s.sequence.kind) << " · " << s.frames << " frames · boxes: " << s.boxes << " · `"
     << s.sequence.path << "`";
  if (s.groundtruth_note) md << " · " << *s.groundtruth_note;
  md << "\n\n";
  if (s.error) {
    md << "**Not run:** " << escape_cell(*s.error) << "\n";
    return;
  }
  accuracy_table(md, s, failed);
  place_table(md, s);
  const bool any_realtime = std::any_of(s.configs.begin(), s.configs.end(),
                                        [](const auto& c) { return has_mode(c, Mode::kRealtime); });
  if (any_realtime) realtime_table(md, s);
  stage_table(md, s, &ConfigResult::stages_ms,
              threaded ? "threaded" : (sequential ? "sequential" : "real-time"));
  if (any_realtime && (sequential || threaded))
    stage_table(md, s, &ConfigResult::stages_ms_realtime, "real-time");
  if (!s.published.empty()) published_table(md, s);
}

/// The runs that failed and the sequences that could not be read.
void failed_runs_table(std::ostream& md, const std::vector<SequenceResult>& sequences,
                       const std::vector<const RunRecord*>& failed) {
  md << "\n## Failed runs\n\n";
  const bool unreadable = std::any_of(sequences.begin(), sequences.end(),
                                      [](const SequenceResult& s) { return s.error.has_value(); });
  if (failed.empty() && !unreadable) {
    md << "None.\n";
    return;
  }
  md << "| sequence | configuration | mode | run | error |\n|---|---|---|---|---|\n";
  for (const SequenceResult& s : sequences)
    if (s.error)
      md << "| " << s.sequence.name << " | all | – | – | " << escape_cell(*s.error) << " |\n";
  for (const RunRecord* r : failed)
    md << "| " << r->sequence << " | " << r->config << " | " << to_string(r->mode) << " | "
       << r->index << " | " << escape_cell(r->error) << " |\n";
}

}  // namespace

std::string markdown(const BenchMeta& meta, const std::vector<SequenceResult>& sequences) {
  const bool sequential = std::count(meta.modes.begin(), meta.modes.end(), Mode::kSequential);
  const bool threaded = std::count(meta.modes.begin(), meta.modes.end(), Mode::kThreaded);
  std::ostringstream md;
  markdown_header(md, meta, sequential, threaded);
  std::vector<const RunRecord*> failed;
  for (const SequenceResult& s : sequences) sequence_section(md, s, sequential, threaded, failed);
  failed_runs_table(md, sequences, failed);
  return md.str();
}

std::string runs_csv(const std::vector<SequenceResult>& sequences) {
  std::ostringstream csv;
  csv << "sequence,dataset,config,mode,run,ok,error,note,frames,ate_rmse_m,rpe_trans_1s_m,"
         "rpe_rot_1s_deg,tracked_ratio,fps,tracking_median_ms,dynamics_mean_ms,wall_s,output,"
         "unsmoothed_ate_rmse_m\n";
  for (const SequenceResult& s : sequences)
    for (const ConfigResult& c : s.configs)
      for (const RunRecord& r : c.runs)
        csv << csv_field(r.sequence) << ',' << to_string(s.sequence.kind) << ',' << r.config << ','
            << to_string(r.mode) << ',' << r.index << ',' << (r.ok ? 1 : 0) << ','
            << csv_field(r.error) << ',' << csv_field(r.note) << ',' << r.frames << ','
            << csv_number(r.ate_rmse_m) << ',' << csv_number(r.rpe_trans_m) << ','
            << csv_number(r.rpe_rot_deg) << ',' << csv_number(r.tracked_ratio) << ','
            << csv_number(r.fps) << ',' << csv_number(r.tracking_ms) << ','
            << csv_number(r.dynamics_ms) << ',' << csv_number(r.wall_s) << ','
            << csv_field(r.output) << ',' << csv_number(r.unsmoothed_ate_rmse_m) << '\n';
  return csv.str();
}

nlohmann::json to_json(const std::optional<Spread>& s) {
  if (!s) return nullptr;
  return {{"median", s->median}, {"min", s->min}, {"max", s->max}, {"n", s->n}};
}

nlohmann::json to_json(const RunRecord& r) {
  return {{"mode", to_string(r.mode)},
          {"index", r.index},
          {"ok", r.ok},
          {"error", optional_text(r.ok ? std::nullopt : std::optional(r.error))},
          {"note", optional_text(r.note.empty() ? std::nullopt : std::optional(r.note))},
          {"frames", r.frames},
          {"ate_rmse_m", optional_number(r.ate_rmse_m)},
          {"unsmoothed_ate_rmse_m", optional_number(r.unsmoothed_ate_rmse_m)},
          {"rpe_trans_m", optional_number(r.rpe_trans_m)},
          {"rpe_rot_deg", optional_number(r.rpe_rot_deg)},
          {"tracked_ratio", optional_number(r.tracked_ratio)},
          {"fps", optional_number(r.fps)},
          {"tracking_ms", optional_number(r.tracking_ms)},
          {"dynamics_ms", optional_number(r.dynamics_ms)},
          {"processed_ratio", optional_number(r.processed_ratio)},
          {"latency_ms", optional_number(r.latency_ms)},
          {"detector_rate_hz", optional_number(r.detector_rate_hz)},
          {"wall_s", r.wall_s},
          {"stages_ms", stages_json(r.stages_ms)},
          {"output", r.output}};
}

nlohmann::json results_json(const BenchMeta& meta, const std::vector<SequenceResult>& sequences) {
  nlohmann::json j;
  j["format"] = "mcslam-bench-results";
  j["version"] = 1;
  j["created_utc"] = meta.created_utc;
  j["command"] = meta.command;
  j["machine"] = {{"hostname", meta.hostname}, {"cpus", meta.cpus}};
  j["runs_per_mode"] = meta.runs_per_mode;
  j["modes"] = nlohmann::json::array();
  for (Mode m : meta.modes) j["modes"].push_back(to_string(m));
  j["wall_time_s"] = meta.wall_time_s;
  j["executor"] = meta.executor.empty() ? nlohmann::json(nullptr) : nlohmann::json(meta.executor);
  j["sequences"] = nlohmann::json::array();
  for (const SequenceResult& s : sequences) {
    nlohmann::json js = {{"name", s.sequence.name},
                         {"dataset", to_string(s.sequence.kind)},
                         {"path", s.sequence.path},
                         {"frames", s.frames},
                         {"boxes", s.boxes},
                         {"error", optional_text(s.error)},
                         {"results", nlohmann::json::array()}};
    for (const ConfigResult& c : s.configs) {
      nlohmann::json runs = nlohmann::json::array();
      for (const RunRecord& r : c.runs) runs.push_back(to_json(r));
      js["results"].push_back({{"config", c.config.name},
                               {"skipped", optional_text(c.skipped)},
                               {"ate_rmse_m", to_json(c.ate)},
                               {"unsmoothed_ate_rmse_m", to_json(c.ate_unsmoothed)},
                               {"online_ate_rmse_m", to_json(c.ate_online)},
                               {"ate_rmse_threaded_m", to_json(c.ate_threaded)},
                               {"rpe_trans_m", to_json(c.rpe_trans)},
                               {"rpe_rot_deg", to_json(c.rpe_rot_deg)},
                               {"tracked_ratio", to_json(c.tracked)},
                               {"fps", to_json(c.fps)},
                               {"tracking_ms", to_json(c.tracking_ms)},
                               {"dynamics_ms", optional_number(c.dynamics_ms)},
                               {"stages_ms", stages_json(c.stages_ms)},
                               // Real-time runs (null without any).
                               {"ate_rmse_realtime_m", to_json(c.ate_realtime)},
                               {"realtime_processed_ratio", to_json(c.processed)},
                               {"realtime_latency_ms", to_json(c.latency_ms)},
                               {"realtime_detector_rate_hz", to_json(c.detector_rate_hz)},
                               {"realtime_fps", to_json(c.fps_realtime)},
                               {"stages_ms_realtime", stages_json(c.stages_ms_realtime)},
                               {"runs", runs}});
    }
    j["sequences"].push_back(js);
  }
  return j;
}

}  // namespace mcslam::app::bench
