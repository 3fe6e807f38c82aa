#include "mcslam/io/association.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

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

}  // namespace mcslam::io
