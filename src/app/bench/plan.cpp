#include "mcslam/app/bench/plan.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>

#include "mcslam/core/error.hpp"

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool is_sequence_dir(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / "rgb.txt", ec) && fs::is_regular_file(dir / "depth.txt", ec);
}

bool written_by_synth(const fs::path& dir) {
  std::ifstream in(dir / "rgb.txt");
  std::string line;
  for (int i = 0; i < 3 && std::getline(in, line); ++i)
    if (line.rfind('#', 0) == 0 && line.find("mcslam synth") != std::string::npos) return true;
  return false;
}

bool same_path(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  return fs::equivalent(a, b, ec);
}

}  // namespace

const char* to_string(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kTum:
      return "TUM";
    case DatasetKind::kBonn:
      return "Bonn";
    case DatasetKind::kSynthetic:
      return "synthetic";
    case DatasetKind::kOther:
      break;
  }
  return "other";
}

DatasetKind dataset_kind(const std::string& sequence_dir) {
  const fs::path dir = fs::path(sequence_dir).lexically_normal();
  const std::string name = lower((dir.has_filename() ? dir : dir.parent_path()).filename());
  if (name.find("bonn") != std::string::npos) return DatasetKind::kBonn;
  if (name.find("freiburg") != std::string::npos || name.find("rgbd_dataset") != std::string::npos)
    return DatasetKind::kTum;
  if (written_by_synth(dir)) return DatasetKind::kSynthetic;
  return DatasetKind::kOther;
}

std::vector<Sequence> discover_sequences(const std::vector<std::string>& roots,
                                         const std::string& exclude) {
  std::vector<fs::path> found;
  for (const std::string& root : roots) {
    std::error_code ec;
    if (!fs::is_directory(root, ec))
      throw InputError(
          file_error(root, fs::exists(root, ec) ? "is not a folder" : "no such folder"));
    const fs::path base = fs::path(root).lexically_normal();
    if (is_sequence_dir(base)) {
      found.push_back(base);
      continue;
    }
    fs::recursive_directory_iterator it(base, fs::directory_options::skip_permission_denied, ec);
    if (ec) throw InputError(file_error(root, "cannot be read: " + ec.message()));
    for (const fs::recursive_directory_iterator end; it != end; it.increment(ec)) {
      if (ec) throw InputError(file_error(root, "cannot be read: " + ec.message()));
      std::error_code dir_ec;
      if (!it->is_directory(dir_ec)) continue;
      const fs::path path = it->path();
      const std::string leaf = path.filename().string();
      if (leaf.empty() || leaf[0] == '.' || (!exclude.empty() && same_path(path, exclude))) {
        it.disable_recursion_pending();
        continue;
      }
      if (is_sequence_dir(path)) {
        found.push_back(path.lexically_normal());
        it.disable_recursion_pending();
      }
    }
  }
  std::sort(found.begin(), found.end(), [](const fs::path& a, const fs::path& b) {
    return a.filename() != b.filename() ? a.filename() < b.filename() : a < b;
  });
  found.erase(std::unique(found.begin(), found.end(),
                          [](const fs::path& a, const fs::path& b) { return same_path(a, b); }),
              found.end());

  std::vector<Sequence> sequences;
  std::map<std::string, int> seen;
  for (const fs::path& path : found) {
    Sequence s;
    s.name = path.filename().string();
    // (append, not "-" + ...: GCC 12 misreports -Wrestrict on that concatenation)
    if (const int n = ++seen[s.name]; n > 1) s.name.append("-").append(std::to_string(n));
    s.path = path.string();
    s.kind = dataset_kind(s.path);
    std::error_code ec;
    if (fs::is_regular_file(path / "detections.json", ec))
      s.detections_file = (path / "detections.json").string();
    sequences.push_back(std::move(s));
  }
  return sequences;
}

std::vector<Sequence> filter_sequences(const std::vector<Sequence>& sequences,
                                       const std::vector<std::string>& filters) {
  if (filters.empty()) return sequences;
  std::vector<Sequence> kept;
  for (const std::string& f : filters) {
    const bool any = std::any_of(sequences.begin(), sequences.end(), [&](const Sequence& s) {
      return s.name.find(f) != std::string::npos;
    });
    if (!any) throw InputError("--sequences: no sequence found matches '" + f + "'");
  }
  for (const Sequence& s : sequences)
    if (std::any_of(filters.begin(), filters.end(),
                    [&](const std::string& f) { return s.name.find(f) != std::string::npos; }))
      kept.push_back(s);
  return kept;
}

const std::vector<Config>& all_configs() {
  static const std::vector<Config> configs = {
      {"points", "points", "ORB points only", "points", false, false},
      {"lines", "+lines", "points and LSD/LBD line segments", "points,lines", false, false},
      {"planes", "+planes", "points, lines and depth planes", "points,lines,planes", false, false},
      {"detection", "+detection",
       "all features; object boxes, dynamic objects excluded (Algorithm 1)", "points,lines,planes",
       true, false},
      {"full", "+moving constraints (full)",
       "the full system: Algorithm 1, and Algorithm 2 with residuals (9) and (10)",
       "points,lines,planes", true, true},
  };
  return configs;
}

std::vector<Config> select_configs(const std::vector<std::string>& names) {
  const std::vector<Config>& all = all_configs();
  if (names.empty()) return all;
  for (const std::string& n : names)
    if (std::none_of(all.begin(), all.end(), [&](const Config& c) { return c.name == n; }))
      throw InputError("--configs: unknown configuration '" + n +
                       "' (use a comma-separated subset of points,lines,planes,detection,full)");
  std::vector<Config> selected;
  for (const Config& c : all)
    if (std::find(names.begin(), names.end(), c.name) != names.end()) selected.push_back(c);
  return selected;
}

const char* to_string(Mode mode) {
  switch (mode) {
    case Mode::kSequential:
      return "sequential";
    case Mode::kThreaded:
      return "threaded";
    case Mode::kRealtime:
      return "realtime";
  }
  return "threaded";
}

std::vector<Mode> select_modes(const std::vector<std::string>& names) {
  if (names.empty()) return {Mode::kSequential, Mode::kThreaded};
  bool sequential = false, threaded = false, realtime = false;
  for (const std::string& n : names) {
    if (n == "sequential")
      sequential = true;
    else if (n == "threaded")
      threaded = true;
    else if (n == "realtime")
      realtime = true;
    else
      throw InputError("--modes: unknown mode '" + n +
                       "' (use sequential, threaded, realtime or several)");
  }
  std::vector<Mode> modes;
  if (sequential) modes.push_back(Mode::kSequential);
  if (threaded) modes.push_back(Mode::kThreaded);
  if (realtime) modes.push_back(Mode::kRealtime);
  return modes;
}

std::string BoxSource::describe() const {
  if (detections) return fs::path(*detections).filename().string() + " in the sequence";
  if (model) return fs::path(*model).filename().string();
  return "none";
}

BoxSource box_source_for(const Sequence& sequence, const std::optional<std::string>& model) {
  BoxSource source;
  if (sequence.detections_file)
    source.detections = sequence.detections_file;
  else
    source.model = model;
  return source;
}

std::string run_folder_name(Mode mode, int index) {
  return std::string(to_string(mode)) + "-" + std::to_string(index);
}

std::vector<std::string> run_arguments(const RunSpec& spec, const BoxSource& boxes, int max_frames,
                                       std::optional<double> confidence) {
  std::vector<std::string> args = {"run",
                                   spec.sequence->path,
                                   "--output",
                                   spec.output_dir,
                                   spec.mode == Mode::kSequential ? "--sequential" : "--threaded",
                                   "--features",
                                   spec.config->features,
                                   "--quiet"};
  if (spec.config->boxes) {
    if (boxes.detections) {
      args.insert(args.end(), {"--detections", *boxes.detections});
    } else if (boxes.model) {
      args.insert(args.end(), {"--model", *boxes.model});
      if (confidence) args.insert(args.end(), {"--confidence", std::to_string(*confidence)});
    }
    if (!spec.config->constraints) args.push_back("--no-constraints");
  }
  if (spec.mode == Mode::kRealtime) args.push_back("--realtime");
  if (max_frames > 0) args.insert(args.end(), {"--max-frames", std::to_string(max_frames)});
  if (spec.save_map) args.push_back("--save-map");
  if (spec.save_overlays) args.push_back("--save-overlays");
  return args;
}

}  // namespace mcslam::app::bench
