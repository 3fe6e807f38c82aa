#include "mcslam/io/association.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <tuple>

#include "mcslam/core/error.hpp"

namespace mcslam::io {

std::vector<std::pair<std::size_t, std::size_t>> associate_stamps(const std::vector<double>& rgb,
                                                                  const std::vector<double>& depth,
                                                                  double max_difference) {
  struct Candidate {
    double difference;
    std::size_t rgb_index;
    std::size_t depth_index;
  };
  std::vector<Candidate> candidates;
  // Both lists are sorted, so each colour image's window of close depth images starts at or
  // after the previous one's.
  std::size_t window_start = 0;
  for (std::size_t i = 0; i < rgb.size(); ++i) {
    const double t = rgb[i];
    while (window_start < depth.size() && t - depth[window_start] >= max_difference) ++window_start;
    for (std::size_t j = window_start; j < depth.size(); ++j) {
      const double difference = std::abs(t - depth[j]);
      if (depth[j] >= t && difference >= max_difference) break;
      if (difference < max_difference) candidates.push_back({difference, i, j});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.difference, a.rgb_index, a.depth_index) <
           std::tie(b.difference, b.rgb_index, b.depth_index);
  });
  std::vector<bool> rgb_used(rgb.size(), false);
  std::vector<bool> depth_used(depth.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const Candidate& c : candidates) {
    if (rgb_used[c.rgb_index] || depth_used[c.depth_index]) continue;
    rgb_used[c.rgb_index] = true;
    depth_used[c.depth_index] = true;
    matches.emplace_back(c.rgb_index, c.depth_index);
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

namespace {

std::string seconds(double t) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6f", t);
  return text;
}

}  // namespace

RecordingPairs pair_recording(const std::string& path, const std::string& rgb_topic,
                              const std::string& depth_topic, const std::vector<double>& rgb,
                              const std::vector<double>& depth, double max_difference,
                              std::vector<std::string>& warnings) {
  RecordingPairs out;
  for (const auto& [topic, stamps] : {std::pair{&rgb_topic, &rgb}, std::pair{&depth_topic, &depth}})
    if (stamps->empty()) throw InputError(file_error(path, "topic '" + *topic + "' has no images"));
  out.pairs = associate_stamps(rgb, depth, max_difference);
  if (out.pairs.empty())
    throw InputError(file_error(
        path, "no colour image has a depth image within " + seconds(max_difference) +
                  " s (colour " + seconds(rgb.front()) + "-" + seconds(rgb.back()) + ", depth " +
                  seconds(depth.front()) + "-" + seconds(depth.back()) + ")"));
  for (const auto& [r, d] : out.pairs)
    out.frames.push_back({rgb[r], path + ":" + rgb_topic + "#" + std::to_string(r), depth[d],
                          path + ":" + depth_topic + "#" + std::to_string(d)});
  const std::size_t unpaired = rgb.size() - out.pairs.size();
  if (unpaired > 0)
    warnings.push_back(file_error(path, std::to_string(unpaired) +
                                            " colour images have no depth image within " +
                                            seconds(max_difference) + " s; skipped"));
  return out;
}

void sort_by_time_unique(Trajectory& poses) {
  std::stable_sort(poses.begin(), poses.end(), [](const StampedPose& a, const StampedPose& b) {
    return a.timestamp < b.timestamp;
  });
  poses.erase(std::unique(poses.begin(), poses.end(),
                          [](const StampedPose& a, const StampedPose& b) {
                            return a.timestamp == b.timestamp;
                          }),
              poses.end());
}

void check_recorded_images(const std::string& path, const RecordedImages& rgb,
                           const RecordedImages& depth) {
  for (const RecordedImages* images : {&rgb, &depth})
    if (images->messages == 0)
      throw InputError(file_error(path, "topic '" + images->topic + "' has no messages"));
  if (depth.width != rgb.width || depth.height != rgb.height)
    throw InputError(file_error(
        path, "depth images ('" + depth.topic + "') are " + std::to_string(depth.width) + "x" +
                  std::to_string(depth.height) + " but the colour images ('" + rgb.topic +
                  "') are " + std::to_string(rgb.width) + "x" + std::to_string(rgb.height) +
                  " (register the depth to the colour camera)"));
}

}  // namespace mcslam::io
