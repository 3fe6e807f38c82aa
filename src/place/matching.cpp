#include "mcslam/place/matching.hpp"

#include <algorithm>
#include <limits>
#include <unordered_map>

namespace mcslam::place {

std::vector<features::DescriptorMatch> match_by_words(
    const FeatureVector& a, const std::vector<features::OrbDescriptor>& da, const FeatureVector& b,
    const std::vector<features::OrbDescriptor>& db, const WordMatchOptions& options,
    const std::function<bool(int)>& use_a, const std::function<bool(int)>& use_b) {
  // b feature -> the best match claiming it so far.
  std::unordered_map<int, features::DescriptorMatch> best_for_b;
  auto ia = a.begin();
  auto ib = b.begin();
  while (ia != a.end() && ib != b.end()) {
    if (ia->first < ib->first) {
      ++ia;
      continue;
    }
    if (ib->first < ia->first) {
      ++ib;
      continue;
    }
    for (int qa : ia->second) {
      if (qa < 0 || static_cast<std::size_t>(qa) >= da.size() || (use_a && !use_a(qa))) continue;
      int best = std::numeric_limits<int>::max(), second = std::numeric_limits<int>::max();
      int best_index = -1;
      for (int tb : ib->second) {
        if (tb < 0 || static_cast<std::size_t>(tb) >= db.size() || (use_b && !use_b(tb))) continue;
        const int d = features::hamming_distance(da[static_cast<std::size_t>(qa)],
                                                 db[static_cast<std::size_t>(tb)]);
        if (d < best) {
          second = best;
          best = d;
          best_index = tb;
        } else if (d < second) {
          second = d;
        }
      }
      if (best_index < 0 || best > options.max_distance) continue;
      if (second != std::numeric_limits<int>::max() &&
          static_cast<float>(best) >= options.ratio * static_cast<float>(second))
        continue;
      auto [it, inserted] =
          best_for_b.emplace(best_index, features::DescriptorMatch{qa, best_index, best});
      if (!inserted &&
          (best < it->second.distance || (best == it->second.distance && qa < it->second.query)))
        it->second = {qa, best_index, best};
    }
    ++ia;
    ++ib;
  }
  std::vector<features::DescriptorMatch> out;
  out.reserve(best_for_b.size());
  for (const auto& kv : best_for_b) out.push_back(kv.second);
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) { return x.query < y.query; });
  return out;
}

}  // namespace mcslam::place
