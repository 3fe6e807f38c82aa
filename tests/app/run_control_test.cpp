// RunControl: a pause is asked for at once but holds the loop only between two frames.
#include "mcslam/app/run_control.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

namespace mcslam::app {
namespace {

bool eventually(const std::function<bool()>& condition) {
  for (int i = 0; i < 500; ++i) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return condition();
}

TEST(RunControl, APauseHoldsTheLoopOnlyOnceItWaitsBetweenFrames) {
  RunControl control;
  control.pause();
  EXPECT_TRUE(control.paused());
  EXPECT_FALSE(control.held());  // the frame in flight has not finished yet

  std::atomic<bool> returned{false};
  std::thread loop([&] {
    control.wait_while_paused(nullptr);
    returned = true;
  });
  EXPECT_TRUE(eventually([&] { return control.held(); }));
  EXPECT_FALSE(returned);
  control.resume();
  loop.join();
  EXPECT_TRUE(returned);
  EXPECT_FALSE(control.paused());
  EXPECT_FALSE(control.held());
  EXPECT_EQ(control.summary()["pauses"], 1);
}

TEST(RunControl, AStopReleasesAHeldLoop) {
  RunControl control;
  control.pause();
  std::atomic<bool> stop{false};
  std::thread loop([&] { control.wait_while_paused([&] { return stop.load(); }); });
  EXPECT_TRUE(eventually([&] { return control.held(); }));
  stop = true;
  control.wake();
  loop.join();
  EXPECT_FALSE(control.held());
  EXPECT_TRUE(control.paused());
}

TEST(RunControl, AnUnpausedLoopNeverWaits) {
  RunControl control;
  EXPECT_EQ(control.wait_while_paused(nullptr), 0.0);
  EXPECT_FALSE(control.held());
}

}  // namespace
}  // namespace mcslam::app
