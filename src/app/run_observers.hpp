#pragma once
// The observers of `mcslam run`'s frames that write its outputs (private to run.cpp): what each
// frame adds to timings.csv, objects.json, overlays/, status.json and the progress bar.

#include <cstddef>
#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/app/frame_observer.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/optim/pose_filter.hpp"

namespace mcslam::app {

/// Resident memory of this process now, in MiB (Linux), 0 when unknown.
double current_rss_mib();

/// status.json: how far a run got, rewritten atomically at each change of state and at
/// checkpoints, so that a killed run is recognisable as partial.
class RunStatus {
 public:
  RunStatus(std::string path, std::size_t frames_total);
  void running(std::size_t frames_done) { write("running", frames_done, {}); }
  void finished(bool interrupted, std::size_t frames_done) {
    write(interrupted ? "interrupted" : "complete", frames_done, {});
  }
  /// Best effort: the error is reported to the caller anyway.
  void failed(const std::string& error);

 private:
  void write(const std::string& state, std::size_t frames_done, const std::string& error);

  std::string path_;
  std::size_t frames_total_;
  std::size_t frames_done_ = 0;
};

/// Per-frame stage times, compactly: the value of stage k (in first-seen order) or 0.
struct StageTable {
  std::vector<std::string> names;
  std::map<std::string, std::size_t> index;
  std::vector<std::vector<float>> rows;

  void add_frame(const StageTimes& times);
  double at(std::size_t frame, std::size_t stage) const {
    return stage < rows[frame].size() ? rows[frame][stage] : 0.0;
  }
};

/// Every frame's figures: the rows of timings.csv and the counters and samples of summary.json.
class FrameRecorder : public FrameObserver {
 public:
  void on_frame(const FrameEvent& event) override;
  /// timings.csv; with `realtime` the dropped_before and latency_ms columns.
  std::string timings_csv(bool realtime) const;

  int tracked = 0, lost = 0, relocalised = 0, keyframes_inserted = 0;
  StageTable stage_table;
  std::map<std::string, std::vector<double>> stage_samples;
  std::vector<double> tracking_ms, load_ms, latency_ms, reloc_query_ms;
  /// Per lagged pose given out (tracker.pose_filter.lag): how far its frame's time lies behind
  /// the frame that gave it out, and in real time its latency (that delay plus the frame's).
  std::vector<double> lagged_delay_ms, lagged_latency_ms;
  std::vector<std::size_t> dropped_before;
  std::vector<float> rss_mib;
  nlohmann::json reloc_events = nlohmann::json::array();
  bool reloc_by_database = false;
  int reloc_attempts = 0;  // lost frames that tried to find their pose again
  int recovered = 0;  // relocalisations from the pose before the loss (tracker.recovery_window)
  std::map<std::string, std::vector<double>> counts;  // per-frame feature and inlier counts
  std::map<optim::FilterOutcome, int> online_poses;   // tracked frames per pose filter outcome

 private:
  std::vector<std::string> frame_prefix_;
};

/// objects.json, streamed to its temporary file frame by frame (a long run holds none of it),
/// and the figures of summary.json's "dynamics".
class ObjectsRecorder : public FrameObserver {
 public:
  /// Without `path` only the figures are kept.
  explicit ObjectsRecorder(std::optional<std::string> path);
  void on_frame(const FrameEvent& event) override;
  /// Closes and commits objects.json (when it has frames).
  void commit();

  std::vector<double> detect_ms, detection_age, propagation_iou, stale_iou;
  std::map<std::string, int> object_states;  // box-frames per state
  int frames_with_boxes = 0, fresh_frames = 0, mover_frames = 0;

 private:
  std::optional<io::AtomicFile> file_;
};

/// overlays/<frame>.jpg (--save-overlays).
class OverlayWriter : public FrameObserver {
 public:
  explicit OverlayWriter(std::filesystem::path folder) : folder_(std::move(folder)) {}
  void on_frame(const FrameEvent& event) override;

 private:
  std::filesystem::path folder_;
};

/// Figures of one pass of a repeated run, taken as its last frame is done.
struct PassFigures {
  int frames = 0, tracked = 0, lost = 0, relocalised = 0, keyframes_inserted = 0;
  std::vector<double> tracking_ms;
  double wall_s = 0.0;
  double rss_end_mib = 0.0;
  std::size_t keyframes_in_map = 0, points_in_map = 0, lines_in_map = 0;
};

/// Soak figures of a repeated run (--repeat), taken when a pass ends or the run stops in one.
class PassRecorder : public FrameObserver {
 public:
  PassRecorder(const FrameRecorder& frames, std::size_t frames_per_pass, std::size_t total)
      : frames_(frames), frames_per_pass_(frames_per_pass), total_(total) {}
  void on_frame(const FrameEvent& event) override;
  void on_stream_end(slam::System& system) override;
  const std::vector<PassFigures>& passes() const { return passes_; }

 private:
  void record(slam::System& system, std::size_t done);

  const FrameRecorder& frames_;
  std::size_t frames_per_pass_, total_;
  std::size_t done_ = 0;
  std::vector<PassFigures> passes_;
  Stopwatch watch_;
};

/// A checkpoint every few seconds (status.json and a partial trajectory_online.txt): what a kill
/// would leave is a clearly partial run.
class Checkpointer : public FrameObserver {
 public:
  Checkpointer(std::filesystem::path out, RunStatus& status, bool live, std::size_t total)
      : out_(std::move(out)), status_(status), live_(live), total_(total) {}
  void on_frame(const FrameEvent& event) override;

 private:
  std::filesystem::path out_;
  RunStatus& status_;
  bool live_;
  std::size_t total_;
  Stopwatch watch_;
};

/// The progress bar on stderr (--quiet turns it off).
class ProgressObserver : public FrameObserver {
 public:
  ProgressObserver(std::size_t total, const FrameRecorder& frames)
      : total_(total), frames_(frames) {}
  void on_frame(const FrameEvent& event) override;

 private:
  std::size_t total_;
  const FrameRecorder& frames_;
  Stopwatch wall_;
};

/// A function called with each frame (RunRequest::on_frame, e.g. the ROS node's publisher).
class CallbackObserver : public FrameObserver {
 public:
  using Callback =
      std::function<void(const slam::FrameResult&, const slam::PreparedImages&, slam::System&)>;
  explicit CallbackObserver(Callback callback) : callback_(std::move(callback)) {}
  void on_frame(const FrameEvent& e) override { callback_(e.result, e.images, e.system); }

 private:
  Callback callback_;
};

/// An object's figures as objects.json lists them.
nlohmann::json objects_json(const slam::FrameResult& r);

}  // namespace mcslam::app
