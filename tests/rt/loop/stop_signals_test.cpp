// StopSignals: SIGINT/SIGTERM are blocked while it lives, collected by wait_for, and the
// previous mask comes back afterwards. Each test is its own process under ctest; run directly,
// the tests still leave no signal pending (each one consumes what it raises).
#include <gtest/gtest.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>

#include "trainer/loop/rt_thread.hpp"
#include "trainer/loop/stop_signals.hpp"

namespace trainer::loop {
namespace {

bool blocked_in_this_thread(int signal_number) {
  sigset_t current;
  sigemptyset(&current);
  pthread_sigmask(SIG_BLOCK, nullptr, &current);
  return sigismember(&current, signal_number) == 1;
}

TEST(StopSignals, RaisedSigtermIsReturnedByWaitFor) {
  StopSignals signals;
  ASSERT_TRUE(blocked_in_this_thread(SIGTERM));
  ASSERT_TRUE(blocked_in_this_thread(SIGINT));
  ASSERT_EQ(raise(SIGTERM), 0);  // stays pending: blocked, no handler runs
  EXPECT_EQ(signals.wait_for(1'000'000'000), SIGTERM);
  EXPECT_EQ(signals.wait_for(0), 0);  // consumed
}

TEST(StopSignals, TimeoutReturnsZero) {
  StopSignals signals;
  EXPECT_EQ(signals.wait_for(20'000'000), 0);
  EXPECT_EQ(signals.wait_for(0), 0);
  EXPECT_EQ(signals.wait_for(-5), 0);  // negative: a poll
}

TEST(StopSignals, ProcessDirectedSigintFromAnotherThreadIsCollected) {
  StopSignals signals;
  // Created after the mask is set, so this thread inherits it and the signal cannot be
  // delivered anywhere; it stays pending on the process until the supervisor waits.
  bool inherited_mask = false;
  auto sender = RtThread::start([&] {
    inherited_mask = blocked_in_this_thread(SIGINT) && blocked_in_this_thread(SIGTERM);
    kill(getpid(), SIGINT);
  });
  ASSERT_TRUE(sender.has_value()) << sender.error().message;
  sender->join();
  EXPECT_TRUE(inherited_mask);
  EXPECT_EQ(signals.wait_for(5'000'000'000), SIGINT);
}

TEST(StopSignals, DestructorRestoresThePreviousMask) {
  const bool was_blocked = blocked_in_this_thread(SIGTERM);
  {
    StopSignals signals;
    EXPECT_TRUE(blocked_in_this_thread(SIGTERM));
  }
  EXPECT_EQ(blocked_in_this_thread(SIGTERM), was_blocked);
  EXPECT_FALSE(blocked_in_this_thread(SIGINT));
}

}  // namespace
}  // namespace trainer::loop
