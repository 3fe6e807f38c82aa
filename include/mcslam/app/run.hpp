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
};

/// Runs the sequence and writes into output_dir: trajectory.txt, keyframes.txt, timings.csv,
/// summary.json and config.yaml. Returns the summary. Throws InputError for bad input.
nlohmann::json run_sequence(const RunRequest& request);

/// One line per figure a person wants to see after a run.
std::string summary_text(const nlohmann::json& summary);

}  // namespace mcslam::app
