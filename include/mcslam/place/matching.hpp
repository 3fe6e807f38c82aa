#pragma once
// Descriptor matching between two images through their direct indices: only features under the
// same vocabulary node are compared, which is what makes relocalisation and loop verification
// fast (a few hundred comparisons per feature become a few).

#include <functional>
#include <vector>

#include "mcslam/features/matching.hpp"
#include "mcslam/features/orb.hpp"
#include "mcslam/place/vocabulary.hpp"

namespace mcslam::place {

struct WordMatchOptions {
  int max_distance = 50;  // Hamming
  float ratio = 0.75f;    // Lowe's ratio between the best and the second best under the node
};

/// For each feature of image a (direct index `a`, descriptors `da`) the closest feature of image
/// b under the same node, kept when it passes max_distance and the ratio test; each b feature
/// is used at most once (the closest a feature keeps it). `use_a` / `use_b`, when given, leave
/// out features (e.g. without depth or without a landmark). Matches are sorted by query index.
std::vector<features::DescriptorMatch> match_by_words(
    const FeatureVector& a, const std::vector<features::OrbDescriptor>& da, const FeatureVector& b,
    const std::vector<features::OrbDescriptor>& db, const WordMatchOptions& options,
    const std::function<bool(int)>& use_a = {}, const std::function<bool(int)>& use_b = {});

}  // namespace mcslam::place
