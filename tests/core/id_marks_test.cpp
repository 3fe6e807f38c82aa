#include "mcslam/core/id_marks.hpp"

#include <gtest/gtest.h>

#include <random>
#include <unordered_set>

namespace mcslam {
namespace {

TEST(IdMarks, MarksEachIdOncePerPass) {
  IdMarks marks;
  EXPECT_FALSE(marks.contains(7));
  EXPECT_TRUE(marks.insert(7));
  EXPECT_FALSE(marks.insert(7));
  EXPECT_TRUE(marks.contains(7));
  EXPECT_FALSE(marks.contains(6));
  EXPECT_FALSE(marks.contains(1000000));  // beyond what was ever marked
  marks.clear();
  EXPECT_FALSE(marks.contains(7));
  EXPECT_TRUE(marks.insert(7));
}

TEST(IdMarks, AgreesWithAHashSetOverManyPasses) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<std::uint64_t> id(0, 5000);
  IdMarks marks;
  for (int pass = 0; pass < 50; ++pass) {
    marks.clear();
    std::unordered_set<std::uint64_t> reference;
    for (int k = 0; k < 400; ++k) {
      const std::uint64_t i = id(rng);
      EXPECT_EQ(marks.insert(i), reference.insert(i).second);
    }
    for (std::uint64_t i = 0; i <= 5000; i += 7)
      EXPECT_EQ(marks.contains(i), reference.count(i) == 1);
  }
}

TEST(IdCounts, CountsAPassAndStartsAgainAfterIt) {
  IdCounts counts;
  for (const std::uint64_t id : {9u, 3u, 9u, 9u, 0u, 3u}) counts.add(id);
  const std::vector<std::pair<int, std::uint64_t>> expected = {{3, 9}, {2, 3}, {1, 0}};
  EXPECT_EQ(counts.take(), expected);
  EXPECT_TRUE(counts.take().empty());
  counts.add(3);
  const std::vector<std::pair<int, std::uint64_t>> again = {{1, 3}};
  EXPECT_EQ(counts.take(), again);
}

}  // namespace
}  // namespace mcslam
