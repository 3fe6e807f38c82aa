#include "mcslam/slam/detection_source.hpp"

#include <filesystem>
#include <sstream>

#include "mcslam/core/thread_priority.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/core/worker.hpp"

namespace mcslam::slam {

FileDetectionSource::FileDetectionSource(perception::DetectionsFile file, std::string path)
    : file_(std::move(file)), path_(std::move(path)) {}

void FileDetectionSource::submit(std::uint64_t frame_id, double timestamp, const cv::Mat&, bool) {
  if (const perception::FrameDetections* f = file_.find(timestamp))
    newest_ = TimedDetections{frame_id, f->detections, 0.0};
}

std::optional<TimedDetections> FileDetectionSource::collect(std::uint64_t, bool) { return newest_; }

std::string FileDetectionSource::describe() const {
  return "detections file " + path_ + " (" + std::to_string(file_.frames.size()) + " frames)";
}

ModelDetectionSource::ModelDetectionSource(perception::Detector detector, int interval,
                                           int niceness)
    : detector_(std::move(detector)), interval_(std::max(1, interval)) {
  worker_ = std::thread([this, niceness] {
    set_current_thread_name("mcslam-detector");
    lower_current_thread_priority(niceness);  // best effort
    run_guarded();
  });
}

void ModelDetectionSource::inject_failure_at(std::int64_t passes) {
  std::lock_guard<std::mutex> lock(mutex_);
  fail_after_passes_ = passes;
}

void ModelDetectionSource::run_guarded() {
  try {
    run();
  } catch (...) {
    failure_.set(std::current_exception());
    {
      // Whoever waits for a frame's boxes is released: the frame goes on without them.
      std::lock_guard<std::mutex> lock(mutex_);
      job_.reset();
      running_.reset();
      stop_ = true;
    }
    cv_.notify_all();
  }
}

ModelDetectionSource::~ModelDetectionSource() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  worker_.join();
}

void ModelDetectionSource::submit(std::uint64_t frame_id, double, const cv::Mat& bgr,
                                  bool required) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stop_) return;  // the worker failed (failure()) or is stopping
    if (!required) {
      if (job_ || running_) return;  // busy: this frame is skipped
      if (last_submitted_ && frame_id < *last_submitted_ + static_cast<std::uint64_t>(interval_))
        return;  // not yet due
    }
    last_submitted_ = frame_id;
    // The detector's own copy: the caller may reuse its buffer as soon as this returns.
    job_.emplace(frame_id, bgr.clone());
  }
  cv_.notify_all();
}

std::optional<TimedDetections> ModelDetectionSource::collect(std::uint64_t frame_id, bool wait) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (wait) {
    cv_.wait(lock, [&] {
      const bool pending = (job_ && job_->first == frame_id) || (running_ && *running_ == frame_id);
      return !pending || stop_;
    });
  }
  return newest_;
}

std::string ModelDetectionSource::describe() const {
  std::ostringstream s;
  s << "model " << std::filesystem::path(detector_.path()).filename().string() << " ("
    << perception::to_string(detector_.format()) << ", " << detector_.input_size().width << "x"
    << detector_.input_size().height;
  if (detector_.input_size() != detector_.graph_input_size())
    s << ", exported for " << detector_.graph_input_size().width << "x"
      << detector_.graph_input_size().height;
  s << ")";
  return s.str();
}

std::vector<double> ModelDetectionSource::pass_times_ms() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pass_ms_;
}

std::size_t ModelDetectionSource::pass_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pass_ms_.size();
}

void ModelDetectionSource::run() {
  for (;;) {
    std::pair<std::uint64_t, cv::Mat> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return job_.has_value() || stop_; });
      if (stop_) return;
      if (fail_after_passes_ >= 0 &&
          static_cast<std::int64_t>(pass_ms_.size()) >= fail_after_passes_)
        throw std::runtime_error("failure injected after " + std::to_string(pass_ms_.size()) +
                                 " passes (--inject-failure)");
      job = std::move(*job_);
      job_.reset();
      running_ = job.first;
    }
    Stopwatch watch;
    // detect() never throws for image content.
    std::vector<perception::Detection> boxes = detector_.detect(job.second);
    const double ms = watch.elapsed_ms();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      newest_ = TimedDetections{job.first, std::move(boxes), ms};
      pass_ms_.push_back(ms);
      running_.reset();
    }
    cv_.notify_all();
  }
}

}  // namespace mcslam::slam
