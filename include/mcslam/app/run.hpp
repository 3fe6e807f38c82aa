#pragma once
// `mcslam run`: a whole sequence through the SLAM system, with its outputs on disk.

#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

namespace mcslam::app {

struct RunRequest {
  std::string sequence_dir;
  std::string output_dir;
  std::optional<std::string> config_path;
  std::optional<std::string> associations_path;
  /// Overrides system.sequential when set.
  std::optional<bool> sequential;
  /// Process at most this many frames (0: all).
  int max_frames = 0;
  /// Progress bar on stderr.
  bool progress = false;
  /// Also write map.ply and map.json (see map/export.hpp).
  bool save_map = false;
  /// Feature kinds to use, overriding the configuration: a comma-separated subset of
  /// "points,lines,planes".
  std::optional<std::string> features;
};

/// Parses a --features list ("points,lines,planes" or a subset); throws InputError naming the
/// unknown kind.
void apply_feature_list(const std::string& list, bool& points, bool& lines, bool& planes);

/// Runs the sequence and writes into output_dir: trajectory.txt, trajectory_online.txt,
/// keyframes.txt, timings.csv, summary.json, config.yaml, and with save_map map.ply and
/// map.json. Returns the summary. Throws InputError for bad input.
nlohmann::json run_sequence(const RunRequest& request);

/// One line per figure a person wants to see after a run.
std::string summary_text(const nlohmann::json& summary);

}  // namespace mcslam::app
