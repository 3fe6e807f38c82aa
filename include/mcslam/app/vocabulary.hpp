#pragma once
// `mcslam vocabulary`: trains a bag-of-words vocabulary (place/vocabulary.hpp) from the ORB
// descriptors of TUM-layout sequences and writes it to a file.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mcslam/features/orb.hpp"
#include "mcslam/place/vocabulary.hpp"

namespace mcslam::app {

struct VocabularyRequest {
  /// Sequence folders (rgb.txt and depth.txt, as for `run`).
  std::vector<std::string> sequences;
  std::string output;
  /// Every this-many-th image of each sequence is a training image (neighbouring frames repeat
  /// each other).
  int every = 5;
  /// At most this many training images per sequence (0: no limit).
  int max_images = 0;
  features::OrbOptions orb;  ///< as tracking extracts them
  place::VocabularyOptions options;
  bool progress = false;  ///< one line per sequence on stderr
};

/// Extracts the descriptors, trains, writes request.output atomically and returns a summary:
/// sequences with their image counts, images, descriptors, words, nodes, file bytes, the
/// vocabulary id (hex) and the seconds spent extracting and training. Throws InputError for a bad
/// request (no sequence, every < 1, max_images < 0, bad options), a missing or malformed
/// sequence, an unreadable image (naming the file) or an output that cannot be written.
nlohmann::json train_vocabulary(const VocabularyRequest& request);

}  // namespace mcslam::app
