#include "mcslam/place/matching.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "descriptors.hpp"

namespace mcslam::place {
namespace {

/// Two views of the same 40 prototypes, the second shuffled: matching through the words finds
/// the true pairs, honours the filters, and never uses a feature of b twice.
TEST(MatchByWords, FindsTheTruePairsOfTwoViews) {
  const test::Training training;
  VocabularyOptions options;
  options.branching = 4;
  options.depth = 3;
  const Vocabulary voc = Vocabulary::train(training.images, options);
  std::mt19937_64 rng(3);
  std::vector<features::OrbDescriptor> a, b;
  for (int p = 0; p < 40; ++p)
    a.push_back(test::noisy(training.protos[static_cast<std::size_t>(p)], 6, rng));
  std::vector<int> order(40);
  for (int k = 0; k < 40; ++k) order[static_cast<std::size_t>(k)] = k;
  std::shuffle(order.begin(), order.end(), rng);
  for (int k : order)
    b.push_back(test::noisy(training.protos[static_cast<std::size_t>(k)], 6, rng));
  const BowImage ia = voc.transform(a, 1), ib = voc.transform(b, 1);
  const auto matches = match_by_words(ia.direct, a, ib.direct, b, WordMatchOptions{});
  ASSERT_GE(matches.size(), 30u);
  std::vector<int> used;
  for (const auto& m : matches) {
    EXPECT_EQ(order[static_cast<std::size_t>(m.train)], m.query);
    EXPECT_LE(m.distance, 50);
    used.push_back(m.train);
  }
  std::sort(used.begin(), used.end());
  EXPECT_EQ(std::unique(used.begin(), used.end()), used.end());
  EXPECT_TRUE(std::is_sorted(matches.begin(), matches.end(),
                             [](const auto& x, const auto& y) { return x.query < y.query; }));

  // Filters: only even features of a, only b features of prototypes below 20.
  const auto filtered = match_by_words(
      ia.direct, a, ib.direct, b, WordMatchOptions{}, [](int q) { return q % 2 == 0; },
      [&](int t) { return order[static_cast<std::size_t>(t)] < 20; });
  ASSERT_FALSE(filtered.empty());
  for (const auto& m : filtered) {
    EXPECT_EQ(m.query % 2, 0);
    EXPECT_LT(m.query, 20);
  }
}

TEST(MatchByWords, SkippedFeaturesTakeNoPart) {
  const test::Training training;
  VocabularyOptions options;
  options.branching = 4;
  options.depth = 3;
  const Vocabulary voc = Vocabulary::train(training.images, options);
  const auto& image = training.images[0];
  std::vector<std::uint8_t> skip(image.size(), 0);
  // The first five prototypes' views (4 each) are skipped.
  for (std::size_t k = 0; k < skip.size() / 2; ++k) skip[k] = 1;
  const BowImage full = voc.transform(image, 1);
  const BowImage half = voc.transform(image, 1, skip);
  std::size_t indexed = 0;
  for (const auto& [node, features] : half.direct)
    for (int f : features) {
      EXPECT_EQ(skip[static_cast<std::size_t>(f)], 0);
      ++indexed;
    }
  EXPECT_EQ(indexed, image.size() / 2);
  EXPECT_LT(half.bow.size(), full.bow.size());
}

}  // namespace
}  // namespace mcslam::place
