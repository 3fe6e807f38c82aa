#include "mapping/ordered_pipeline.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace mcslam::mapping::detail {
namespace {

TEST(OrderedPipeline, GathersEachItemOnceAndAppliesThemInOrderFromTheirSlots) {
  for (const std::size_t helpers : {0u, 1u, 3u}) {
    for (const std::size_t n : {0u, 1u, 2u, 7u, 40u}) {
      for (const std::size_t asked : {0u, 5u}) {
        const std::size_t slots = pipeline_slots(helpers, asked);
        std::vector<std::size_t> in_slot(slots, n);  // the item gathered into each slot
        std::vector<int> gathered(n, 0);
        std::vector<std::size_t> applied;
        std::mutex mutex;
        gather_and_apply_in_order(
            n, helpers, asked,
            [&](std::size_t k, std::size_t slot) {
              EXPECT_EQ(slot, k % slots);
              // Uneven work, so that items finish out of order.
              std::this_thread::sleep_for(std::chrono::microseconds(50 * ((k * 7) % 5)));
              const std::lock_guard lock(mutex);
              ++gathered[k];
              in_slot[slot] = k;
            },
            [&](std::size_t k, std::size_t slot) {
              const std::lock_guard lock(mutex);
              // Its slot still holds it: nothing was gathered there before it was applied.
              EXPECT_EQ(in_slot[slot], k);
              applied.push_back(k);
            });
        for (std::size_t k = 0; k < n; ++k) EXPECT_EQ(gathered[k], 1) << k;
        ASSERT_EQ(applied.size(), n) << helpers << " helpers";
        for (std::size_t k = 0; k < n; ++k) EXPECT_EQ(applied[k], k);
      }
    }
  }
}

TEST(OrderedPipeline, TheFirstFailureStopsTheWorkAndIsThrownAfterTheHelpersReturn) {
  for (const std::size_t helpers : {0u, 2u}) {
    std::atomic<std::size_t> started{0};
    std::vector<std::size_t> applied;
    EXPECT_THROW(gather_and_apply_in_order(
                     100, helpers, 0,
                     [&](std::size_t k, std::size_t) {
                       ++started;
                       if (k == 5) throw std::runtime_error("gather 5");
                     },
                     [&](std::size_t k, std::size_t) { applied.push_back(k); }),
                 std::runtime_error);
    // Items up to 5 + the slots may have started; item 5 and those after are never applied.
    EXPECT_LE(started.load(), 5 + helpers + 1);
    for (const std::size_t k : applied) EXPECT_LT(k, 5u);

    try {
      gather_and_apply_in_order(
          100, helpers, 0, [](std::size_t, std::size_t) {},
          [](std::size_t k, std::size_t) {
            if (k == 3) throw std::logic_error("apply 3");
          });
      ADD_FAILURE() << "no exception";
    } catch (const std::logic_error& e) {
      EXPECT_STREQ(e.what(), "apply 3");
    }
  }
}

}  // namespace
}  // namespace mcslam::mapping::detail
