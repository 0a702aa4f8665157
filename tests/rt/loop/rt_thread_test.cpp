// RtThread: runs its body on a separate thread with the requested stack size and name, joins,
// moves ownership, and refuses bad arguments with a message.
#include <gtest/gtest.h>
#include <pthread.h>

#include <atomic>
#include <cstdint>
#include <string>
#include <utility>

#include "trainer/loop/rt_thread.hpp"

namespace trainer::loop {
namespace {

// Stack size of the calling thread as pthread reports it.
std::size_t own_stack_bytes() {
  pthread_attr_t attributes;
  if (pthread_getattr_np(pthread_self(), &attributes) != 0) return 0;
  std::size_t size_bytes = 0;
  pthread_attr_getstacksize(&attributes, &size_bytes);
  pthread_attr_destroy(&attributes);
  return size_bytes;
}

TEST(RtThread, RunsBodyOnAnotherThreadAndJoins) {
  // Larger than the 8 MiB default, so a size that was not applied shows. glibc may hand out a
  // cached stack up to 4x larger than asked, and may count the guard page: check "at least".
  constexpr std::size_t kStackBytes = std::size_t{12} << 20;
  const pthread_t caller = pthread_self();
  bool ran_elsewhere = false;
  std::size_t stack_bytes = 0;
  auto thread = RtThread::start(
      [&] {
        ran_elsewhere = pthread_equal(pthread_self(), caller) == 0;
        stack_bytes = own_stack_bytes();
      },
      kStackBytes);
  ASSERT_TRUE(thread.has_value()) << thread.error().message;
  EXPECT_TRUE(thread->joinable());
  thread->join();
  EXPECT_FALSE(thread->joinable());
  EXPECT_TRUE(ran_elsewhere);  // join() makes the body's writes visible here
  EXPECT_GE(stack_bytes, kStackBytes);
  thread->join();  // joining again is a no-op
}

TEST(RtThread, NameIsVisibleOnTheThread) {
  std::string name;
  auto thread = RtThread::start(
      [&] {
        // The name is set by the creator right after pthread_create; wait until it shows.
        char buffer[16] = {};
        for (int attempt = 0; attempt < 1000; ++attempt) {
          pthread_getname_np(pthread_self(), buffer, sizeof buffer);
          if (std::string(buffer) == "haptic-test") break;
          sched_yield();
        }
        name = buffer;
      },
      RtThread::kDefaultStackBytes, "haptic-test");
  ASSERT_TRUE(thread.has_value()) << thread.error().message;
  thread->join();
  EXPECT_EQ(name, "haptic-test");
}

TEST(RtThread, DestructorJoinsAndMoveTransfersOwnership) {
  std::atomic<int> finished{0};
  {
    auto started = RtThread::start([&] { finished.fetch_add(1); });
    ASSERT_TRUE(started.has_value()) << started.error().message;
    RtThread moved(std::move(*started));
    EXPECT_FALSE(started->joinable());
    EXPECT_TRUE(moved.joinable());

    RtThread assigned;
    EXPECT_FALSE(assigned.joinable());
    assigned = std::move(moved);
    // Checking the moved-from state is the point here.
    // NOLINTNEXTLINE(bugprone-use-after-move,clang-analyzer-cplusplus.Move)
    EXPECT_FALSE(moved.joinable());
    EXPECT_TRUE(assigned.joinable());
  }  // `assigned` joins here
  EXPECT_EQ(finished.load(), 1);

  // Move-assigning over a running thread joins it first.
  auto first = RtThread::start([&] { finished.fetch_add(10); });
  auto second = RtThread::start([&] { finished.fetch_add(100); });
  ASSERT_TRUE(first.has_value() && second.has_value());
  *first = std::move(*second);
  EXPECT_GE(finished.load(), 11);  // the first body has returned
  first->join();
  EXPECT_EQ(finished.load(), 111);
}

TEST(RtThread, RefusesBadArgumentsWithAMessage) {
  auto empty = RtThread::start(std::function<void()>{});
  ASSERT_FALSE(empty.has_value());
  EXPECT_NE(empty.error().message.find("empty"), std::string::npos);

  auto tiny = RtThread::start([] {}, 1024);
  ASSERT_FALSE(tiny.has_value());
  EXPECT_NE(tiny.error().message.find("PTHREAD_STACK_MIN"), std::string::npos);

  auto long_name = RtThread::start([] {}, RtThread::kDefaultStackBytes, "a-name-that-is-too-long");
  ASSERT_FALSE(long_name.has_value());
  EXPECT_NE(long_name.error().message.find("at most 15"), std::string::npos);
}

}  // namespace
}  // namespace trainer::loop
