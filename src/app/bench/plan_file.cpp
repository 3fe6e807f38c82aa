#include "mcslam/app/bench/plan_file.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

constexpr const char* kPlanHeader = "sequence\tconfig\tmode\tindex\targuments";

const char* to_string(BenchExecutor executor) {
  return executor == BenchExecutor::kSlurm ? "slurm" : "local";
}

std::optional<Mode> mode_named(const std::string& name) {
  for (Mode m : {Mode::kSequential, Mode::kThreaded, Mode::kRealtime})
    if (name == to_string(m)) return m;
  return std::nullopt;
}

std::optional<DatasetKind> dataset_named(const std::string& name) {
  for (DatasetKind k :
       {DatasetKind::kTum, DatasetKind::kBonn, DatasetKind::kSynthetic, DatasetKind::kOther})
    if (name == to_string(k)) return k;
  return std::nullopt;
}

std::string read_text(const fs::path& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::error_code ec;
    throw InputError(file_error(path.string(),
                                fs::exists(path, ec) ? "cannot be read" : "no such file: " + what));
  }
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

nlohmann::json sequences_json(const std::vector<Sequence>& sequences) {
  nlohmann::json j = nlohmann::json::array();
  for (const Sequence& s : sequences)
    j.push_back({{"name", s.name},
                 {"path", s.path},
                 {"dataset", to_string(s.kind)},
                 {"detections", s.detections_file ? nlohmann::json(*s.detections_file)
                                                  : nlohmann::json(nullptr)}});
  return j;
}

nlohmann::json slurm_json(const SlurmOptions& o) {
  return {{"partition", o.partition},
          {"time_limit_min", o.time_limit_min},
          {"array_limit", o.array_limit},
          {"sbatch_args", o.sbatch_args}};
}

template <typename T>
std::optional<T> optional_at(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || j.at(key).is_null()) return std::nullopt;
  return j.at(key).get<T>();
}

Sequence sequence_from(const nlohmann::json& j) {
  Sequence s;
  s.name = j.at("name").get<std::string>();
  s.path = j.at("path").get<std::string>();
  const auto kind = dataset_named(j.at("dataset").get<std::string>());
  if (!kind) throw InputError("sequence '" + s.name + "': unknown dataset");
  s.kind = *kind;
  s.detections_file = optional_at<std::string>(j, "detections");
  if (s.name.empty() || s.name.find_first_of("\t\n/") != std::string::npos)
    throw InputError("sequence name '" + s.name + "' is empty or holds a tab, '/' or line break");
  return s;
}

/// The settings' fields from their JSON; json exceptions and InputErrors for bad values.
BenchSettings settings_from(const nlohmann::json& j) {
  if (j.value("format", "") != "mcslam-bench-plan")
    throw InputError("not a bench's settings (\"format\" is not \"mcslam-bench-plan\")");
  BenchSettings s;
  s.command = j.at("command").get<std::string>();
  s.created_utc = j.at("created_utc").get<std::string>();
  const std::string executor = j.at("executor").get<std::string>();
  if (executor != "local" && executor != "slurm")
    throw InputError("\"executor\" must be \"local\" or \"slurm\", not \"" + executor + "\"");
  s.executor = executor == "slurm" ? BenchExecutor::kSlurm : BenchExecutor::kLocal;
  s.jobs = j.at("jobs").get<int>();
  s.runs = j.at("runs").get<int>();
  s.modes = select_modes(j.at("modes").get<std::vector<std::string>>());
  s.configs = select_configs(j.at("configs").get<std::vector<std::string>>());
  for (const auto& seq : j.at("sequences")) s.sequences.push_back(sequence_from(seq));
  s.model = optional_at<std::string>(j, "model");
  s.confidence = optional_at<double>(j, "confidence");
  s.max_frames = j.at("max_frames").get<int>();
  s.timeout_s = j.at("timeout_s").get<double>();
  s.overlays = j.at("overlays").get<int>();
  const nlohmann::json& slurm = j.at("slurm");
  s.slurm.partition = slurm.at("partition").get<std::string>();
  s.slurm.time_limit_min = slurm.at("time_limit_min").get<int>();
  s.slurm.array_limit = slurm.at("array_limit").get<int>();
  s.slurm.sbatch_args = slurm.at("sbatch_args").get<std::vector<std::string>>();
  return s;
}

void check_settings(const BenchSettings& s) {
  if (s.runs < 1) throw InputError("\"runs\" must be at least 1");
  if (s.jobs < 1) throw InputError("\"jobs\" must be at least 1");
  if (s.modes.empty() || s.configs.empty())
    throw InputError("\"modes\" and \"configs\" must not be empty");
  if (s.sequences.empty()) throw InputError("\"sequences\" is empty");
  std::set<std::string> names;
  for (const Sequence& q : s.sequences)
    if (!names.insert(q.name).second) throw InputError("sequence '" + q.name + "' twice");
  if (auto e = s.slurm.check()) throw InputError("\"slurm\": " + *e);
}

std::vector<std::string> split_tabs(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t tab = line.find('\t', start);
    fields.push_back(line.substr(start, tab - start));
    if (tab == std::string::npos) return fields;
    start = tab + 1;
  }
}

/// The value of --output (also -o and --output=) in `run` arguments; nullopt when there is
/// none, InputError when there are several.
std::optional<std::string> output_argument(const std::vector<std::string>& args) {
  std::optional<std::string> value;
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::optional<std::string> v;
    if ((args[i] == "--output" || args[i] == "-o") && i + 1 < args.size())
      v = args[++i];
    else if (args[i].rfind("--output=", 0) == 0)
      v = args[i].substr(9);
    if (!v) continue;
    if (value) throw InputError("--output is given twice");
    value = v;
  }
  return value;
}

/// True when the last components of `path` are those of `folder`.
bool ends_with_folder(const std::string& path, const std::string& folder) {
  std::vector<std::string> a, b;
  for (const auto& c : fs::path(path).lexically_normal())
    if (!c.empty() && c != ".") a.push_back(c.string());
  for (const auto& c : fs::path(folder)) b.push_back(c.string());
  return a.size() >= b.size() && std::equal(b.rbegin(), b.rend(), a.rbegin());
}

bool has(const std::vector<std::string>& args, const char* flag) {
  return std::find(args.begin(), args.end(), flag) != args.end();
}

/// The `run` arguments of a plan line agree with its columns.
void check_arguments(const PlannedRun& run) {
  const auto& args = run.arguments;
  if (args.empty() || args.front() != "run")
    throw InputError("the arguments must start with 'run' (those of `mcslam run`)");
  if (args.size() < 2 || args[1].empty() || args[1][0] == '-')
    throw InputError("'run' must be followed by the sequence folder");
  const auto output = output_argument(args);
  if (!output) throw InputError("the arguments have no --output");
  if (!ends_with_folder(*output, run.folder()))
    throw InputError("--output " + *output + " is not the run's folder " + run.folder() +
                     " (the tables read each run from its folder)");
  const bool sequential = has(args, "--sequential"), realtime = has(args, "--realtime");
  const bool agrees = run.mode == Mode::kSequential ? sequential && !realtime
                      : run.mode == Mode::kRealtime ? realtime && !sequential
                                                    : !sequential && !realtime;
  if (!agrees)
    throw InputError(std::string("mode ") + to_string(run.mode) +
                     " does not match the arguments (sequential: --sequential, threaded: "
                     "neither --sequential nor --realtime, realtime: --realtime)");
}

int parse_index(const std::string& text, int runs) {
  std::size_t used = 0;
  int index = 0;
  try {
    index = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || index < 1 || index > runs)
    throw InputError("index '" + text + "' is not a number from 1 to " + std::to_string(runs) +
                     " (the bench's runs per mode)");
  return index;
}

/// One line of the plan, checked against the settings.
PlannedRun parse_line(const std::string& line, const BenchSettings& settings) {
  const std::vector<std::string> f = split_tabs(line);
  if (f.size() < 6)
    throw InputError(
        "expected tab-separated columns sequence, config, mode, index and the "
        "`mcslam run` arguments; found " +
        std::to_string(f.size()) + " column(s)");
  PlannedRun run;
  run.sequence = f[0];
  run.config = f[1];
  if (std::none_of(settings.sequences.begin(), settings.sequences.end(),
                   [&](const Sequence& s) { return s.name == f[0]; }))
    throw InputError("sequence '" + f[0] + "' is not one of the bench's (" + kSettingsFile + ")");
  if (std::none_of(settings.configs.begin(), settings.configs.end(),
                   [&](const Config& c) { return c.name == f[1]; }))
    throw InputError("configuration '" + f[1] + "' is not one of the bench's (" + kSettingsFile +
                     ")");
  const auto mode = mode_named(f[2]);
  if (!mode ||
      std::find(settings.modes.begin(), settings.modes.end(), *mode) == settings.modes.end())
    throw InputError("mode '" + f[2] + "' is not one of the bench's (" + kSettingsFile + ")");
  run.mode = *mode;
  run.index = parse_index(f[3], settings.runs);
  run.arguments.assign(f.begin() + 4, f.end());
  if (std::any_of(run.arguments.begin(), run.arguments.end(),
                  [](const std::string& a) { return a.empty(); }))
    throw InputError("an empty argument (two tabs in a row?)");
  check_arguments(run);
  return run;
}

}  // namespace

std::string PlannedRun::folder() const {
  return (fs::path("runs") / sequence / config / run_folder_name(mode, index)).string();
}

std::string PlannedRun::output() const {
  try {
    return output_argument(arguments).value_or("");
  } catch (const InputError&) {
    return "";
  }
}

std::string PlannedRun::describe() const {
  return sequence + " · " + config + " · " + to_string(mode) + " " + std::to_string(index);
}

nlohmann::json settings_json(const BenchSettings& s) {
  std::vector<std::string> modes, configs;
  for (Mode m : s.modes) modes.push_back(to_string(m));
  for (const Config& c : s.configs) configs.push_back(c.name);
  return {{"format", "mcslam-bench-plan"},
          {"version", 1},
          {"command", s.command},
          {"created_utc", s.created_utc},
          {"executor", to_string(s.executor)},
          {"jobs", s.jobs},
          {"runs", s.runs},
          {"modes", modes},
          {"configs", configs},
          {"sequences", sequences_json(s.sequences)},
          {"model", s.model ? nlohmann::json(*s.model) : nlohmann::json(nullptr)},
          {"confidence", s.confidence ? nlohmann::json(*s.confidence) : nlohmann::json(nullptr)},
          {"max_frames", s.max_frames},
          {"timeout_s", s.timeout_s},
          {"overlays", s.overlays},
          {"slurm", slurm_json(s.slurm)}};
}

BenchSettings parse_settings(const std::string& text, const std::string& path) {
  try {
    BenchSettings s = settings_from(nlohmann::json::parse(text));
    check_settings(s);
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file_error(path, std::string("not a bench's settings: ") + e.what()));
  } catch (const InputError& e) {
    throw InputError(file_error(path, e.what()));
  }
}

std::string plan_tsv(const std::vector<PlannedRun>& runs) {
  std::ostringstream s;
  s << "# mcslam bench plan: one run per line, tab-separated: sequence, configuration, mode,\n"
       "# index, then the arguments of `mcslam run`, one per column. Each run writes into\n"
       "# runs/<sequence>/<config>/<mode>-<index>/; Slurm array task i runs the i-th line\n"
       "# below the header (from 0). The bench's settings are in bench.json.\n"
    << kPlanHeader << "\n";
  for (const PlannedRun& run : runs) {
    std::vector<std::string> fields = {run.sequence, run.config, to_string(run.mode),
                                       std::to_string(run.index)};
    fields.insert(fields.end(), run.arguments.begin(), run.arguments.end());
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].find_first_of("\t\n\r") != std::string::npos)
        throw InputError("'" + fields[i] + "': a tab or line break cannot go into " + kPlanFile);
      s << (i ? "\t" : "") << fields[i];
    }
    s << "\n";
  }
  return s.str();
}

std::vector<PlannedRun> parse_plan(const std::string& text, const std::string& path,
                                   const BenchSettings& settings) {
  std::vector<PlannedRun> runs;
  std::set<std::string> folders;
  std::istringstream in(text);
  bool header = false;
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::string where = path + ":" + std::to_string(number);
    if (!header) {
      if (line.rfind(kPlanHeader, 0) != 0)
        throw InputError(where + ": expected the header row '" + std::string(kPlanHeader) +
                         "' (tab-separated) before the runs");
      header = true;
      continue;
    }
    try {
      runs.push_back(parse_line(line, settings));
    } catch (const InputError& e) {
      throw InputError(where + ": " + e.what());
    }
    if (!folders.insert(runs.back().folder()).second)
      throw InputError(where + ": " + runs.back().describe() + " is planned twice");
  }
  if (!header) throw InputError(file_error(path, "no header row: not a bench plan"));
  return runs;
}

void write_plan_files(const std::string& dir, const PlanFiles& plan) {
  const std::string tsv = plan_tsv(plan.runs);  // throws before anything is written
  io::write_file_atomic((fs::path(dir) / kSettingsFile).string(),
                        settings_json(plan.settings).dump(1) + "\n");
  io::write_file_atomic((fs::path(dir) / kPlanFile).string(), tsv);
}

PlanFiles read_plan_files(const std::string& dir) {
  const fs::path settings_path = fs::path(dir) / kSettingsFile;
  const fs::path plan_path = fs::path(dir) / kPlanFile;
  const std::string what = dir + " is not a bench folder (mcslam bench writes " + kSettingsFile +
                           " and " + kPlanFile + " into its --output)";
  PlanFiles plan;
  plan.settings = parse_settings(read_text(settings_path, what), settings_path.string());
  plan.runs = parse_plan(read_text(plan_path, what), plan_path.string(), plan.settings);
  return plan;
}

}  // namespace mcslam::app::bench
