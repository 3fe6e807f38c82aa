#pragma once
// A binary bag-of-words vocabulary for ORB descriptors (the idea of DBoW2, written for mcslam):
// a tree of `branching` children per node and `depth` levels, built by hierarchical k-majority
// clustering (k-medians under the Hamming distance: each centre is the bitwise majority of its
// members), whose leaves are the words. Each word carries an IDF weight, log(N / n_w) over the N
// training images, n_w of which hold the word. An image becomes a TF-IDF vector, L1-normalised,
// and two images are compared with the L1 score 1 - |a - b|_1 / 2, in [0, 1]. The direct index
// groups an image's features by their node a few levels above the words, so that matching two
// images only compares features under the same node.
//
//   Vocabulary voc = Vocabulary::train(descriptors_per_image, options);
//   BowVector a = voc.transform(image_a).bow, b = voc.transform(image_b).bow;
//   double s = score(a, b);
//
// The file format (save/load) is little-endian binary: "MCSLVOC\0", format version, branching,
// depth, node and word counts, the nodes (descriptor, first child, child count, word weight),
// and an FNV-1a 64-bit checksum of everything before it.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "mcslam/features/orb.hpp"

namespace mcslam::place {

struct VocabularyOptions {
  /// Children per node (k) and levels below the root (L): at most k^L words. 10 and 5 give up to
  /// 100,000 words, a 4.6 MB file.
  int branching = 10;
  int depth = 5;
  /// k-majority iterations per node; clustering stops earlier when no assignment changes.
  int iterations = 10;
  /// Seed of the k-means++ initialisation (training is deterministic for a seed).
  std::uint64_t seed = 1;

  std::optional<std::string> check() const;
};

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

/// (word, weight) pairs sorted by word, weights positive and summing to 1.
using BowVector = std::vector<std::pair<WordId, double>>;
/// Direct index: node (at Vocabulary::direct_level) -> indices of the image's features under it.
using FeatureVector = std::map<NodeId, std::vector<int>>;

struct BowImage {
  BowVector bow;
  FeatureVector direct;
};

/// The file format's checksum: FNV-1a, 64 bits, of `bytes`.
std::uint64_t file_checksum(std::string_view bytes);

/// L1 score of two L1-normalised vectors: 1 for identical ones, 0 when they share no word.
double score(const BowVector& a, const BowVector& b);

class Vocabulary {
 public:
  /// Builds the tree from the descriptors of a set of training images (at least one
  /// descriptor). Throws InputError when the options are invalid or there is nothing to train on.
  static Vocabulary train(const std::vector<std::vector<features::OrbDescriptor>>& images,
                          const VocabularyOptions& options);

  /// Reads a file written by save(). Throws InputError "<path>: <problem>" for a missing,
  /// truncated, foreign, corrupt or wrong-version file.
  static Vocabulary load(const std::string& path);
  /// Writes the vocabulary atomically. Throws InputError when the file cannot be written.
  void save(const std::string& path) const;

  /// The word of a descriptor: the leaf reached by descending to the closest child at every level.
  WordId word_of(const features::OrbDescriptor& descriptor) const;
  /// The BoW vector of an image, and its direct index at `levels_up` levels above the words
  /// (clamped to the root).
  /// Descriptors whose entry in `skip` is non-zero (features of moving objects) take no part:
  /// they add no weight and are not in the direct index; indices stay those of `descriptors`.
  BowImage transform(const std::vector<features::OrbDescriptor>& descriptors, int levels_up = 2,
                     const std::vector<std::uint8_t>& skip = {}) const;

  int words() const { return static_cast<int>(words_.size()); }
  int nodes() const { return static_cast<int>(nodes_.size()); }
  int branching() const { return branching_; }
  int depth() const { return depth_; }
  double weight(WordId word) const { return nodes_[words_[word]].weight; }
  /// 64-bit identifier of the vocabulary's content (its checksum): a saved map names the
  /// vocabulary it was built with.
  std::uint64_t id() const { return id_; }

 private:
  struct Node {
    features::OrbDescriptor descriptor;
    NodeId first_child = 0;
    std::uint32_t children = 0;
    double weight = 0.0;  // IDF weight (words only)
    WordId word = 0;      // words only
    int level = 0;        // 0 for the root
  };
  Vocabulary() = default;
  /// The child of `parent` (which has children) closest to `descriptor`.
  NodeId closest_child(NodeId parent, const features::OrbDescriptor& descriptor) const;
  std::string serialise_body() const;
  void finish();  // words_, levels and id_ from nodes_

  int branching_ = 0;
  int depth_ = 0;
  std::vector<Node> nodes_;    // nodes_[0] is the root; children are contiguous
  std::vector<NodeId> words_;  // word id -> node
  std::uint64_t id_ = 0;
};

}  // namespace mcslam::place
