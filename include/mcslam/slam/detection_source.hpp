#pragma once
// Where a frame's object boxes come from: a detector model run on its own thread, overlapped
// with feature extraction, or a detections file (boxes computed elsewhere).
//
// Threading contract (DetectionSource::collect): a frame is given to the detector when it
// arrives (submit), if the detector is free; a busy detector skips it. When the frame's features
// are ready, the tracker takes the newest finished boxes: the frame's own when they are done (or
// when `wait` is set), otherwise those of an earlier frame, marked with their age in frames.
// The tracker grows such boxes by 5% per frame of age (up to 30%) before using them.

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mcslam/core/thread_failure.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/perception/detector.hpp"

namespace mcslam::slam {

struct TimedDetections {
  std::uint64_t frame_id = 0;  ///< the frame whose image was detected
  std::vector<perception::Detection> boxes;
  double detect_ms = 0.0;  ///< the forward pass and decoding (0 for a file)
};

class DetectionSource {
 public:
  virtual ~DetectionSource() = default;
  /// Frame `frame_id` has arrived (raw BGR image, not modified by the caller afterwards).
  /// `required`: the frame will wait for its own boxes (collect with `wait`), so it is detected
  /// even when the detector is busy or the frame is not due: it then replaces any frame still
  /// queued and runs next.
  virtual void submit(std::uint64_t frame_id, double timestamp, const cv::Mat& bgr,
                      bool required = false) = 0;
  /// The newest boxes for frame `frame_id` (see the header comment); nullopt when none exist
  /// yet. With `wait`, blocks until the frame's own detection (if submitted) is finished.
  virtual std::optional<TimedDetections> collect(std::uint64_t frame_id, bool wait) = 0;
  /// For logs and summaries: "model yolov8n_320.onnx (YOLOv8, 320x320)" or "file ...".
  virtual std::string describe() const = 0;
  /// The time (ms) of every forward pass run so far, in order (none for a file): the detector's
  /// actual rate is their count over the run's wall time.
  virtual std::vector<double> pass_times_ms() const { return {}; }
  /// How many forward passes have run so far (pass_times_ms().size(), without the copy).
  virtual std::size_t pass_count() const { return 0; }
  /// The failure of the source's own thread (none for a file): once it threw, no more boxes
  /// come and System reports it (BackgroundThreadError).
  virtual const ThreadFailure* failure() const { return nullptr; }
};

/// Boxes read from a detections file, looked up by timestamp. A frame whose timestamp is not in
/// the file gets the newest earlier frame's boxes, with their age.
class FileDetectionSource final : public DetectionSource {
 public:
  FileDetectionSource(perception::DetectionsFile file, std::string path);
  void submit(std::uint64_t frame_id, double timestamp, const cv::Mat& bgr,
              bool required = false) override;
  std::optional<TimedDetections> collect(std::uint64_t frame_id, bool wait) override;
  std::string describe() const override;

 private:
  perception::DetectionsFile file_;
  std::string path_;
  std::optional<TimedDetections> newest_;
};

/// A detector model on its own thread.
class ModelDetectionSource final : public DetectionSource {
 public:
  /// `interval`: a frame is given to the detector only when at least this many frames have
  /// passed since the last one it was given (1: whenever it is free). `niceness` is added to
  /// the worker thread's nice value (SystemOptions::detector_niceness).
  explicit ModelDetectionSource(perception::Detector detector, int interval = 1, int niceness = 0);
  ~ModelDetectionSource() override;
  ModelDetectionSource(const ModelDetectionSource&) = delete;
  ModelDetectionSource& operator=(const ModelDetectionSource&) = delete;

  void submit(std::uint64_t frame_id, double timestamp, const cv::Mat& bgr,
              bool required = false) override;
  std::optional<TimedDetections> collect(std::uint64_t frame_id, bool wait) override;
  std::string describe() const override;
  std::vector<double> pass_times_ms() const override;
  std::size_t pass_count() const override;
  const ThreadFailure* failure() const override { return &failure_; }
  /// Testing the failure path: the forward pass after this many throws std::runtime_error
  /// (`mcslam run --inject-failure detector:N`). -1: never.
  void inject_failure_at(std::int64_t passes);

 private:
  void run();
  void run_guarded();

  perception::Detector detector_;
  mutable std::mutex mutex_;
  std::vector<double> pass_ms_;  // every forward pass
  std::condition_variable cv_;
  std::optional<std::pair<std::uint64_t, cv::Mat>> job_;  // waiting for the worker
  std::optional<std::uint64_t> running_;                  // frame being detected
  std::optional<TimedDetections> newest_;
  std::optional<std::uint64_t> last_submitted_;
  int interval_ = 1;
  bool stop_ = false;
  std::int64_t fail_after_passes_ = -1;
  ThreadFailure failure_{"detector (mcslam-detector)"};
  std::thread worker_;
};

}  // namespace mcslam::slam
