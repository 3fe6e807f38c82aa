#include "mcslam/features/matching.hpp"

#include <limits>

namespace mcslam::features {

std::vector<DescriptorMatch> match_descriptors(const std::vector<OrbDescriptor>& query,
                                               const std::vector<OrbDescriptor>& train,
                                               int max_distance, float ratio, bool mutual) {
  std::vector<DescriptorMatch> matches;
  if (query.empty() || train.empty()) return matches;
  constexpr int kNone = std::numeric_limits<int>::max();
  // Nearest query of every train descriptor, gathered in the same pass (for the mutual check).
  std::vector<int> train_best(train.size(), kNone);
  std::vector<int> train_best_query(train.size(), -1);
  std::vector<DescriptorMatch> candidates;
  candidates.reserve(query.size());
  for (std::size_t q = 0; q < query.size(); ++q) {
    int best = kNone;
    int second = kNone;
    int best_train = -1;
    for (std::size_t t = 0; t < train.size(); ++t) {
      const int d = hamming_distance(query[q], train[t]);
      if (d < best) {
        second = best;
        best = d;
        best_train = static_cast<int>(t);
      } else if (d < second) {
        second = d;
      }
      if (d < train_best[t]) {
        train_best[t] = d;
        train_best_query[t] = static_cast<int>(q);
      }
    }
    if (best > max_distance) continue;
    if (second != kNone && !(static_cast<float>(best) < ratio * static_cast<float>(second)))
      continue;
    candidates.push_back({static_cast<int>(q), best_train, best});
  }
  matches.reserve(candidates.size());
  for (const DescriptorMatch& m : candidates) {
    if (mutual && train_best_query[static_cast<std::size_t>(m.train)] != m.query) continue;
    matches.push_back(m);
  }
  return matches;
}

}  // namespace mcslam::features
