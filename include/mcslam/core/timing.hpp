#pragma once
// Per-stage wall-clock timing of the per-frame pipeline.

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace mcslam {

class Stopwatch {
 public:
  Stopwatch() : start_(Clock::now()) {}
  void restart() { start_ = Clock::now(); }
  double elapsed_ms() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

/// The stages of one frame, in the order they ran, with their durations in milliseconds.
/// A stage that ran on another thread alongside the frame's own (feature extraction in
/// parallel) is listed with its duration but left out of the total, which is the frame's wall
/// time; the frame's wait for it is a stage of its own.
struct StageTimes {
  std::vector<std::pair<std::string, double>> stages;
  std::vector<std::string> concurrent;  ///< names of the stages left out of total_ms()

  void add(std::string name, double ms) { stages.emplace_back(std::move(name), ms); }
  void add_concurrent(std::string name, double ms) {
    concurrent.push_back(name);
    stages.emplace_back(std::move(name), ms);
  }
  double total_ms() const {
    double sum = 0.0;
    for (const auto& s : stages)
      if (std::find(concurrent.begin(), concurrent.end(), s.first) == concurrent.end())
        sum += s.second;
    return sum;
  }
};

/// Median and p95 etc. of a set of samples (the samples are copied and sorted).
struct SampleStats {
  double median = 0.0;
  double p95 = 0.0;
  double mean = 0.0;
  double max = 0.0;
  std::size_t count = 0;
};
SampleStats compute_stats(std::vector<double> samples);

}  // namespace mcslam
