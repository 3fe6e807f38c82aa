#pragma once
// What `mcslam bench` runs: the sequences found under the data roots, the ablation
// configurations, and the `mcslam run` arguments of one run.

#include <optional>
#include <string>
#include <vector>

namespace mcslam::app::bench {

enum class DatasetKind { kTum, kBonn, kSynthetic, kOther };

/// "TUM", "Bonn", "synthetic", "other".
const char* to_string(DatasetKind kind);

struct Sequence {
  std::string name;  ///< folder name, made unique with a "-2", "-3" suffix when needed
  std::string path;
  DatasetKind kind = DatasetKind::kOther;
  /// The sequence's own boxes (detections.json in its folder), used before any --model.
  std::optional<std::string> detections_file;
};

/// Dataset of a sequence folder: "bonn" in its name gives Bonn, "freiburg" or "rgbd_dataset"
/// TUM, a folder written by `mcslam synth` (its rgb.txt header says so) synthetic.
DatasetKind dataset_kind(const std::string& sequence_dir);

/// Every TUM-layout sequence (a folder holding rgb.txt and depth.txt) under the roots, a root
/// itself included; sequences are not searched for nested ones, and hidden folders and
/// `exclude` (the bench's own output) are skipped. Sorted by name, then path. Throws InputError
/// naming a root that is not a readable folder.
std::vector<Sequence> discover_sequences(const std::vector<std::string>& roots,
                                         const std::string& exclude = "");

/// Keeps the sequences whose name contains one of `filters` (all when empty); throws InputError
/// naming a filter that matches none.
std::vector<Sequence> filter_sequences(const std::vector<Sequence>& sequences,
                                       const std::vector<std::string>& filters);

/// One column of the ablation: each adds one part of the system to the one before.
struct Config {
  std::string name;          ///< points, lines, planes, detection, full
  std::string label;         ///< as the tables show it
  std::string description;   ///< one sentence
  std::string features;      ///< --features list
  bool boxes = false;        ///< needs object boxes (a model or detections.json)
  bool constraints = false;  ///< Algorithm 2 and residuals (9), (10)
};

/// The five configurations, in ablation order.
const std::vector<Config>& all_configs();

/// The named configurations, in ablation order (all when `names` is empty); throws InputError
/// for an unknown name.
std::vector<Config> select_configs(const std::vector<std::string>& names);

/// kRealtime: threaded, with frames delivered at their timestamps (`run --realtime`).
enum class Mode { kSequential, kThreaded, kRealtime };
const char* to_string(Mode mode);

/// Parses "sequential" / "threaded" / "realtime" (sequential and threaded, in that order, when
/// `names` is empty); throws InputError for anything else.
std::vector<Mode> select_modes(const std::vector<std::string>& names);

/// Where a sequence's boxes come from for the configurations that need them.
struct BoxSource {
  std::optional<std::string> detections;  ///< a detections file
  std::optional<std::string> model;       ///< an ONNX detector
  std::string describe() const;           ///< for tables: file or model name, or "none"
  bool any() const { return detections || model; }
};

/// The sequence's own detections.json wins over the bench's --model.
BoxSource box_source_for(const Sequence& sequence, const std::optional<std::string>& model);

struct RunSpec {
  const Sequence* sequence = nullptr;
  const Config* config = nullptr;
  Mode mode = Mode::kSequential;
  int index = 1;  ///< 1-based run number within (sequence, config, mode)
  std::string output_dir;
  bool save_map = false;
  bool save_overlays = false;
};

/// Run-folder name of a spec inside DIR/runs/<sequence>/<config>/: "sequential-1".
std::string run_folder_name(Mode mode, int index);

/// Arguments of `mcslam run` (without the executable) for one run.
std::vector<std::string> run_arguments(const RunSpec& spec, const BoxSource& boxes, int max_frames,
                                       std::optional<double> confidence);

}  // namespace mcslam::app::bench
