#include "mcslam/features/matching.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

namespace mcslam::features {
namespace {

OrbDescriptor random_descriptor(std::mt19937_64& rng) {
  OrbDescriptor d;
  for (auto& b : d.bytes) b = static_cast<std::uint8_t>(rng() >> 56);
  return d;
}

OrbDescriptor flip_bits(OrbDescriptor d, int bits, std::mt19937_64& rng) {
  std::vector<int> order(256);
  std::iota(order.begin(), order.end(), 0);
  for (int i = 0; i < bits; ++i) {  // partial Fisher-Yates: distinct bits
    const int j = i + static_cast<int>(rng() % static_cast<std::uint64_t>(256 - i));
    std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
    const int bit = order[static_cast<std::size_t>(i)];
    d.bytes[static_cast<std::size_t>(bit / 8)] ^= static_cast<std::uint8_t>(1u << (bit % 8));
  }
  return d;
}

TEST(MatchDescriptors, FindsPerturbedCopies) {
  std::mt19937_64 rng(3);
  std::vector<OrbDescriptor> train;
  for (int i = 0; i < 300; ++i) train.push_back(random_descriptor(rng));
  // Queries: noisy copies of train[perm[i]] for the first 200, unrelated descriptors after.
  std::vector<int> perm(300);
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), rng);
  std::vector<OrbDescriptor> query;
  for (int i = 0; i < 200; ++i)
    query.push_back(
        flip_bits(train[static_cast<std::size_t>(perm[static_cast<std::size_t>(i)])], 20, rng));
  for (int i = 0; i < 50; ++i) query.push_back(random_descriptor(rng));

  const auto matches = match_descriptors(query, train);
  ASSERT_EQ(matches.size(), 200u);
  for (const DescriptorMatch& m : matches) {
    ASSERT_LT(m.query, 200);
    EXPECT_EQ(m.train, perm[static_cast<std::size_t>(m.query)]);
    EXPECT_EQ(m.distance, 20);
  }
  EXPECT_TRUE(std::is_sorted(matches.begin(), matches.end(),
                             [](const auto& a, const auto& b) { return a.query < b.query; }));
}

TEST(MatchDescriptors, RatioMutualAndDistance) {
  std::mt19937_64 rng(4);
  const OrbDescriptor base = random_descriptor(rng);
  // Two train descriptors almost equally close to the query: ambiguous -> rejected by the ratio.
  const std::vector<OrbDescriptor> train{flip_bits(base, 10, rng), flip_bits(base, 11, rng)};
  EXPECT_TRUE(match_descriptors({base}, train).empty());
  EXPECT_EQ(match_descriptors({base}, train, 50, 1.0f).size(), 1u);
  // Too far.
  const OrbDescriptor far = flip_bits(base, 60, rng);
  EXPECT_TRUE(match_descriptors({base}, {far}).empty());
  EXPECT_EQ(match_descriptors({base}, {far}, 60).size(), 1u);
  // Mutual: two queries share the same nearest train descriptor; only the closer one keeps it.
  const std::vector<OrbDescriptor> queries{flip_bits(base, 5, rng), flip_bits(base, 15, rng)};
  const auto mutual = match_descriptors(queries, {base});
  ASSERT_EQ(mutual.size(), 1u);
  EXPECT_EQ(mutual[0].query, 0);
  EXPECT_EQ(match_descriptors(queries, {base}, 50, 0.8f, false).size(), 2u);
  EXPECT_TRUE(match_descriptors({}, {base}).empty());
  EXPECT_TRUE(match_descriptors({base}, {}).empty());
}

}  // namespace
}  // namespace mcslam::features
