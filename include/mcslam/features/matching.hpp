#pragma once
// Brute-force descriptor matching (relocalisation, tests).

#include <vector>

#include "mcslam/features/orb.hpp"

namespace mcslam::features {

struct DescriptorMatch {
  int query = -1;
  int train = -1;
  int distance = 0;
};

/// For every query descriptor, its nearest train descriptor (Hamming distance), kept when
/// distance <= max_distance, when it passes Lowe's ratio test (distance < ratio * distance of
/// the second nearest; always passed with a single train descriptor) and, with `mutual`, when
/// the query is also the nearest to that train descriptor (ties go to the lower index).
/// Matches come in increasing query order; each train index is used at most once when mutual.
std::vector<DescriptorMatch> match_descriptors(const std::vector<OrbDescriptor>& query,
                                               const std::vector<OrbDescriptor>& train,
                                               int max_distance = 50, float ratio = 0.8f,
                                               bool mutual = true);

}  // namespace mcslam::features
