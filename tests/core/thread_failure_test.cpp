// ThreadFailure keeps the first exception a thread threw and names the thread when it is
// surfaced; any exception, std::exception or not, is described.
#include "mcslam/core/thread_failure.hpp"

#include <gtest/gtest.h>

#include <new>
#include <stdexcept>
#include <thread>

namespace mcslam {
namespace {

TEST(ThreadFailure, KeepsTheFirstExceptionAndNamesTheThread) {
  ThreadFailure failure("mapper (mcslam-mapper)");
  EXPECT_FALSE(failure.failed());
  EXPECT_EQ(failure.message(), "");
  EXPECT_NO_THROW(failure.throw_if_failed());
  std::thread worker([&] {
    try {
      throw std::bad_alloc();
    } catch (...) {
      failure.set(std::current_exception());
    }
    try {
      throw std::out_of_range("later");
    } catch (...) {
      failure.set(std::current_exception());  // not kept: the first failure stays
    }
  });
  worker.join();
  ASSERT_TRUE(failure.failed());
  EXPECT_EQ(failure.message(), "the mapper (mcslam-mapper) thread failed: std::bad_alloc");
  try {
    failure.throw_if_failed();
    FAIL() << "no exception";
  } catch (const BackgroundThreadError& e) {
    EXPECT_EQ(std::string(e.what()), failure.message());
  }
  EXPECT_THROW(std::rethrow_exception(failure.exception()), std::bad_alloc);
}

TEST(ThreadFailure, DescribesAnyException) {
  EXPECT_EQ(describe_exception(nullptr), "no exception");
  EXPECT_EQ(describe_exception(std::make_exception_ptr(std::runtime_error("x"))), "x");
  EXPECT_EQ(describe_exception(std::make_exception_ptr(42)),
            "an exception that is not a std::exception");
}

}  // namespace
}  // namespace mcslam
