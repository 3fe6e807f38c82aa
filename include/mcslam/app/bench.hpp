#pragma once
// `mcslam bench`: every TUM-layout sequence under the data roots, run N times per ablation
// configuration in sequential mode (accuracy) and threaded mode (speed), each run in its own
// process so that one failure is reported and the rest go on; tables in Markdown, CSV and JSON,
// and a self-contained report.html.

#include <optional>
#include <string>
#include <vector>

namespace mcslam::app {

struct BenchRequest {
  std::vector<std::string> data_roots;
  std::string output_dir;
  int runs = 3;  ///< per configuration and mode
  std::vector<std::string>
      configs;                     ///< subset of points,lines,planes,detection,full; all when empty
  std::vector<std::string> modes;  ///< sequential, threaded; both when empty
  std::vector<std::string> sequences;  ///< keep sequences whose name contains one of these
  std::optional<std::string> model;    ///< detector for sequences without their own detections.json
  std::optional<double> confidence;
  int max_frames = 0;       ///< per run; 0: all
  double timeout_s = 3600;  ///< per run; <= 0: none
  int overlays = 6;         ///< annotated frames per sequence in the report
  bool list_only = false;   ///< print the sequences found and stop
  bool progress = true;     ///< one line per run on stderr
  std::string executable;   ///< mcslam binary for the runs; this process's own when empty
  /// Folder holding report.js (the bundled page scripts); beside the executable when empty.
  std::string report_assets;
  std::string command_line;  ///< as typed, for the tables
};

struct BenchOutcome {
  int runs = 0;
  int failed = 0;             ///< runs that failed
  int sequences_not_run = 0;  ///< sequences that cannot be read
  std::string markdown;       ///< the tables (also in results.md)
  std::string report_path;    ///< empty when the report could not be written
  std::string report_warning;
};

/// Validates the request (InputError: a missing root, no sequence found, runs < 1, an unknown
/// configuration or mode, a missing --model file, an output folder that cannot be made), then
/// runs everything. Failed runs do not throw: they are counted and reported.
BenchOutcome run_bench(const BenchRequest& request);

/// The sequences a bench would run, one per line (name, dataset, boxes, path).
std::string list_sequences(const BenchRequest& request);

}  // namespace mcslam::app
