// The binary bag-of-words vocabulary: training by hierarchical k-majority clustering, words,
// TF-IDF vectors and their L1 score, the direct index, and the file format with its errors.
#include "mcslam/place/vocabulary.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "mcslam/core/error.hpp"
#include "place/descriptors.hpp"
#include "support/temp_dir.hpp"

namespace mcslam::place {
namespace {

using features::OrbDescriptor;
using test::image;
using test::noisy;
using test::Training;

VocabularyOptions small_options() {
  VocabularyOptions o;
  o.branching = 5;
  o.depth = 3;
  return o;
}

const Vocabulary& trained() {
  static const Training t;
  static const Vocabulary voc = Vocabulary::train(t.images, small_options());
  return voc;
}

TEST(VocabularyOptions, DefaultsAreValidAndBadValuesNamed) {
  EXPECT_FALSE(VocabularyOptions{}.check());
  VocabularyOptions o;
  o.branching = 1;
  EXPECT_NE(o.check()->find("branching"), std::string::npos);
  o = {};
  o.depth = 0;
  EXPECT_NE(o.check()->find("depth"), std::string::npos);
  o = {};
  o.iterations = 0;
  EXPECT_NE(o.check()->find("iterations"), std::string::npos);
  EXPECT_THROW(Vocabulary::train({}, VocabularyOptions{}), InputError);
  EXPECT_THROW(Vocabulary::train({{}}, VocabularyOptions{}), InputError);
}

TEST(Vocabulary, TreeShapeAndDeterminism) {
  const Vocabulary& voc = trained();
  EXPECT_EQ(voc.branching(), 5);
  EXPECT_EQ(voc.depth(), 3);
  EXPECT_GT(voc.words(), 50);  // 100 prototypes over at most 125 leaves
  EXPECT_LE(voc.words(), 125);
  EXPECT_GT(voc.nodes(), voc.words());
  const Training t;
  EXPECT_EQ(Vocabulary::train(t.images, small_options()).id(), voc.id()) << "same seed, same tree";
  VocabularyOptions other = small_options();
  other.seed = 2;
  EXPECT_NE(Vocabulary::train(t.images, other).id(), voc.id());
}

TEST(Vocabulary, NoisyViewsOfAPrototypeShareItsWord) {
  const Vocabulary& voc = trained();
  const Training t;
  std::mt19937_64 rng(5);
  int same = 0, total = 0;
  for (const auto& p : t.protos) {
    const WordId w = voc.word_of(p);
    for (int k = 0; k < 10; ++k) {
      same += voc.word_of(noisy(p, 10, rng)) == w ? 1 : 0;
      ++total;
    }
  }
  EXPECT_GE(static_cast<double>(same) / total, 0.95) << same << " of " << total;
}

TEST(Vocabulary, IdfWeightsFollowTheTrainingImages) {
  const Vocabulary& voc = trained();
  const Training t;
  // Each prototype appears in 2 of the 20 images: its word's weight is log(20 / 2) when the word
  // holds that prototype alone.
  int matching = 0;
  for (const auto& p : t.protos)
    matching += std::abs(voc.weight(voc.word_of(p)) - std::log(10.0)) < 1e-5 ? 1 : 0;
  EXPECT_GE(matching, 80);
  for (int w = 0; w < voc.words(); ++w) EXPECT_GE(voc.weight(static_cast<WordId>(w)), 0.0);
}

TEST(Vocabulary, BowVectorsAreNormalisedAndScoreSamePlacesHigh) {
  const Vocabulary& voc = trained();
  const Training t;
  std::mt19937_64 rng(99);
  const auto place0 = image(t.protos, 0, 10, 4, rng);
  const auto place0_again = image(t.protos, 0, 10, 4, rng);
  const auto place5 = image(t.protos, 50, 60, 4, rng);
  const BowVector a = voc.transform(place0).bow;
  const BowVector b = voc.transform(place0_again).bow;
  const BowVector c = voc.transform(place5).bow;
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sum += a[i].second;
    EXPECT_GT(a[i].second, 0.0);
    if (i > 0) {
      EXPECT_LT(a[i - 1].first, a[i].first);
    }
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_NEAR(score(a, a), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(score(a, b), score(b, a));
  EXPECT_GT(score(a, b), 0.8);
  // Different places share a word only where two prototypes fell into one leaf (100
  // prototypes, at most 125 leaves): measured 0.07 here.
  EXPECT_LT(score(a, c), 0.15);
  EXPECT_GT(score(a, b), 5.0 * score(a, c));
  EXPECT_DOUBLE_EQ(score(a, {}), 0.0);
}

TEST(Vocabulary, DirectIndexHoldsEveryFeatureOnceGroupedByNode) {
  const Vocabulary& voc = trained();
  const Training t;
  std::mt19937_64 rng(3);
  const auto features = image(t.protos, 20, 40, 3, rng);
  const BowImage img = voc.transform(features, 1);
  std::vector<int> seen(features.size(), 0);
  for (const auto& [node, indices] : img.direct)
    for (int i : indices) ++seen[static_cast<std::size_t>(i)];
  for (int s : seen) EXPECT_EQ(s, 1);
  // Views of one prototype fall under one node (they share a word, so a node above it).
  const BowImage again = voc.transform(features, 1);
  EXPECT_EQ(again.direct, img.direct);
  EXPECT_LT(img.direct.size(), features.size());
}

TEST(VocabularyFile, RoundTripKeepsTheTreeWeightsAndId) {
  const Vocabulary& voc = trained();
  const mcslam::test::TempDir dir("mcslam_vocabulary_test");
  const std::string path = dir.file("voc.bin");
  voc.save(path);
  const Vocabulary back = Vocabulary::load(path);
  EXPECT_EQ(back.id(), voc.id());
  EXPECT_EQ(back.words(), voc.words());
  EXPECT_EQ(back.nodes(), voc.nodes());
  const Training t;
  std::mt19937_64 rng(4);
  const auto features = image(t.protos, 0, 30, 2, rng);
  EXPECT_EQ(back.transform(features).bow, voc.transform(features).bow);
  // 8 + 20 header bytes, 41 per node, an 8-byte checksum.
  EXPECT_EQ(std::filesystem::file_size(path), 36u + 41u * static_cast<unsigned>(voc.nodes()));
}

TEST(VocabularyFile, BadFilesAreOneClearError) {
  const Vocabulary& voc = trained();
  const mcslam::test::TempDir dir("mcslam_vocabulary_test");
  const std::string good = dir.file("voc.bin");
  voc.save(good);
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const auto expect_error = [&](const std::string& name, const std::string& content,
                                const std::string& problem) {
    const std::string path = dir.write(name, content);
    mcslam::test::expect_input_error([&] { Vocabulary::load(path); }, {path, problem});
  };
  mcslam::test::expect_input_error([&] { Vocabulary::load(dir.file("missing.bin")); },
                                   {"missing.bin", "cannot open"});
  expect_error("empty.bin", "", "bad magic");
  expect_error("foreign.bin", "PK\x03\x04 not a vocabulary at all, just some bytes", "bad magic");
  expect_error("truncated.bin", bytes.substr(0, bytes.size() / 2), "truncated");
  expect_error("header.bin", bytes.substr(0, 20), "truncated");
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  expect_error("flipped.bin", flipped, "checksum");
  std::string version = bytes;
  version[8] = 7;
  expect_error("version.bin", version, "version 7");
}

}  // namespace
}  // namespace mcslam::place
