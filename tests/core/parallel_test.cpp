#include "mcslam/core/parallel.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <utility>
#include <vector>

namespace mcslam {
namespace {

TEST(ParallelFor, CoversEveryIndexOnceWithDisjointSubRanges) {
  for (const std::pair<int, int>& range :
       std::vector<std::pair<int, int>>{{0, 1}, {0, 2}, {0, 8}, {3, 480}, {-5, 7}, {0, 1000}}) {
    const int begin = range.first, end = range.second;  // named: lambdas cannot capture bindings
    std::vector<std::atomic<int>> hits(static_cast<std::size_t>(end - begin));
    std::atomic<int> calls{0};
    parallel_for(begin, end, [&](int first, int last) {
      ASSERT_LE(begin, first);
      ASSERT_LT(first, last);
      ASSERT_LE(last, end);
      ++calls;
      for (int i = first; i < last; ++i) ++hits[static_cast<std::size_t>(i - begin)];
    });
    EXPECT_GE(calls.load(), 1);
    for (std::size_t i = 0; i < hits.size(); ++i)
      EXPECT_EQ(hits[i].load(), 1)
          << "index " << begin + static_cast<int>(i) << " of [" << begin << ", " << end << ")";
  }
}

TEST(ParallelFor, EmptyRangeCallsNothing) {
  int calls = 0;
  parallel_for(4, 4, [&](int, int) { ++calls; });
  parallel_for(5, 2, [&](int, int) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(ParallelFor, WritesOfTheBodiesAreVisibleAfterItReturns) {
  // Plain (non-atomic) writes to disjoint elements: the ThreadSanitizer build checks that the
  // join makes them visible to the caller without a race.
  std::vector<double> out(997, 0.0);
  parallel_for(0, static_cast<int>(out.size()), [&](int first, int last) {
    for (int i = first; i < last; ++i) out[static_cast<std::size_t>(i)] = 0.5 * i;
  });
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], 0.5 * static_cast<double>(i));
}

TEST(ParallelFor, AnExceptionOfABodyReachesTheCaller) {
  EXPECT_THROW(parallel_for(0, 100,
                            [](int first, int last) {
                              if (first <= 42 && 42 < last) throw std::runtime_error("index 42");
                            }),
               std::runtime_error);
}

}  // namespace
}  // namespace mcslam
