#include "mcslam/core/worker.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <pthread.h>
#endif

namespace mcslam {
namespace {

TEST(Worker, RunsTheJobsInOrderOnItsOwnThread) {
  Worker worker("test-worker");
  std::vector<int> order;
  std::vector<std::thread::id> ids;
  for (int k = 0; k < 50; ++k)
    worker.post([&order, &ids, k] {
      order.push_back(k);
      ids.push_back(std::this_thread::get_id());
    });
  worker.wait();
  ASSERT_EQ(order.size(), 50u);
  for (int k = 0; k < 50; ++k) EXPECT_EQ(order[static_cast<std::size_t>(k)], k);
  for (const std::thread::id& id : ids) {
    EXPECT_NE(id, std::this_thread::get_id());
    EXPECT_EQ(id, ids.front());
  }
}

TEST(Worker, WaitReturnsOnlyWhenTheJobHasFinished) {
  Worker worker("test-worker");
  for (int round = 0; round < 20; ++round) {
    std::atomic<bool> done{false};
    worker.post([&done] {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      done = true;
    });
    worker.wait();
    EXPECT_TRUE(done.load()) << round;
  }
  worker.wait();  // nothing posted: returns at once
}

TEST(Worker, WaitRethrowsTheFirstErrorOnceAndTheOtherJobsStillRun) {
  Worker worker("test-worker");
  bool later_ran = false;
  worker.post([] { throw std::runtime_error("first"); });
  worker.post([] { throw std::logic_error("second"); });
  worker.post([&later_ran] { later_ran = true; });
  try {
    worker.wait();
    ADD_FAILURE() << "wait() did not rethrow";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "first");
  }
  EXPECT_TRUE(later_ran);
  EXPECT_NO_THROW(worker.wait());
  int value = 0;
  worker.post([&value] { value = 7; });
  worker.wait();
  EXPECT_EQ(value, 7);
}

TEST(Worker, TheDestructorRunsTheQueuedJobs) {
  std::atomic<int> ran{0};
  {
    Worker worker("test-worker");
    for (int k = 0; k < 10; ++k)
      worker.post([&ran] {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        ++ran;
      });
  }
  EXPECT_EQ(ran.load(), 10);
}

#if defined(__linux__)
TEST(Worker, NamesItsThreadWithinTheSystemLimit) {
  Worker worker("a-name-longer-than-fifteen-bytes");
  char name[32] = {};
  int status = -1;
  worker.post([&] { status = ::pthread_getname_np(::pthread_self(), name, sizeof name); });
  worker.wait();
  ASSERT_EQ(status, 0);
  EXPECT_STREQ(name, "a-name-longer-t");
  EXPECT_EQ(worker.name(), "a-name-longer-than-fifteen-bytes");
}
#endif

}  // namespace
}  // namespace mcslam
