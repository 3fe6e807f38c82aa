#include "mcslam/core/timing.hpp"

#include <gtest/gtest.h>

namespace mcslam {
namespace {

TEST(SampleStats, MedianAndQuantiles) {
  const SampleStats s = compute_stats({5.0, 1.0, 3.0, 2.0, 4.0});
  EXPECT_EQ(s.count, 5u);
  EXPECT_DOUBLE_EQ(s.median, 3.0);
  EXPECT_DOUBLE_EQ(s.mean, 3.0);
  EXPECT_DOUBLE_EQ(s.max, 5.0);
  EXPECT_DOUBLE_EQ(s.p95, 4.8);  // numpy.percentile([1..5], 95)
}

TEST(SampleStats, EmptyIsZero) {
  const SampleStats s = compute_stats({});
  EXPECT_EQ(s.count, 0u);
  EXPECT_DOUBLE_EQ(s.median, 0.0);
}

TEST(StageTimes, Total) {
  StageTimes t;
  t.add("a", 1.5);
  t.add("b", 2.0);
  EXPECT_DOUBLE_EQ(t.total_ms(), 3.5);
}

}  // namespace
}  // namespace mcslam
