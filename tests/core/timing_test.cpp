#include "mcslam/core/timing.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <thread>

#include "mcslam/core/thread_priority.hpp"

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

// --- thread priority -----------------------------------------------------------------------------

TEST(ThreadPriority, LowersOnlyTheCallingThread) {
  const int before = mcslam::current_thread_niceness();
  int inside = before, after_in_thread = before;
  bool lowered = false;
  std::thread t([&] {
    const int start = mcslam::current_thread_niceness();
    lowered = mcslam::lower_current_thread_priority(3);
    after_in_thread = mcslam::current_thread_niceness();
    inside = start;
  });
  t.join();
  EXPECT_EQ(inside, before);  // a new thread starts with its creator's nice value
  if (lowered) {
    EXPECT_EQ(after_in_thread, std::min(before + 3, 19));
  }
  EXPECT_EQ(mcslam::current_thread_niceness(), before) << "the caller's own priority changed";
  EXPECT_TRUE(mcslam::lower_current_thread_priority(0));
  EXPECT_EQ(mcslam::current_thread_niceness(), before);
}
