// Tests for core::ManualClock (deterministic) and core::MonotonicClock (real time; only
// lower bounds and ordering are asserted, never how long a sleep took).
#include "trainer/core/clock.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>

namespace trainer::core {
namespace {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

TEST(ManualClock, StartsWhereToldAndMovesOnlyWhenAdvanced) {
  ManualClock clock(1'000);
  EXPECT_EQ(clock.now_ns(), 1'000);
  EXPECT_EQ(clock.now_ns(), 1'000);
  clock.advance_ns(250);
  EXPECT_EQ(clock.now_ns(), 1'250);
  EXPECT_EQ(ManualClock().now_ns(), 0);
}

TEST(ManualClock, SleepJumpsToTheDeadline) {
  ManualClock clock;
  clock.sleep_until_ns(1'000'000);
  EXPECT_EQ(clock.now_ns(), 1'000'000);
  clock.sleep_until_ns(2'000'000);
  EXPECT_EQ(clock.now_ns(), 2'000'000);
}

TEST(ManualClock, SleepOnAPastDeadlineDoesNotGoBack) {
  ManualClock clock(5'000);
  clock.sleep_until_ns(3'000);
  EXPECT_EQ(clock.now_ns(), 5'000);
  clock.sleep_until_ns(5'000);
  EXPECT_EQ(clock.now_ns(), 5'000);
}

TEST(ManualClock, InjectedWakeLatencyIsAddedAfterTheDeadline) {
  ManualClock clock;
  clock.set_wake_latency_ns(30'000);
  clock.sleep_until_ns(1'000'000);
  EXPECT_EQ(clock.now_ns(), 1'030'000);
  // Waking late for a deadline already passed still costs the latency (an overrun).
  clock.set_wake_latency_ns(7);
  clock.sleep_until_ns(0);
  EXPECT_EQ(clock.now_ns(), 1'030'007);
  clock.set_wake_latency_ns(0);
  clock.sleep_until_ns(2'000'000);
  EXPECT_EQ(clock.now_ns(), 2'000'000);
}

TEST(ManualClock, WorksThroughTheClockInterface) {
  ManualClock manual(10);
  Clock& clock = manual;
  clock.sleep_until_ns(100);
  EXPECT_EQ(clock.now_ns(), 100);
  manual.advance_ns(5);
  EXPECT_EQ(clock.now_ns(), 105);
}

TEST(MonotonicClock, AgreesWithSteadyClockAndNeverGoesBack) {
  MonotonicClock clock;
  const std::int64_t steady_before = steady_now_ns();
  const std::int64_t first = clock.now_ns();
  const std::int64_t steady_after = steady_now_ns();
  // std::chrono::steady_clock is CLOCK_MONOTONIC on Linux: the reading lies between the two.
  EXPECT_LE(steady_before, first);
  EXPECT_LE(first, steady_after);
  EXPECT_GT(first, 0);

  std::int64_t previous = first;
  for (int i = 0; i < 100000; ++i) {
    const std::int64_t now = clock.now_ns();
    ASSERT_GE(now, previous) << "reading " << i;
    previous = now;
  }
}

TEST(MonotonicClock, SleepOnAPastDeadlineReturns) {
  MonotonicClock clock;
  const std::int64_t start = clock.now_ns();
  clock.sleep_until_ns(start - 1'000'000'000);
  clock.sleep_until_ns(start);
  clock.sleep_until_ns(0);
  EXPECT_GE(clock.now_ns(), start);
}

TEST(MonotonicClock, SleepReturnsNoEarlierThanTheDeadline) {
  MonotonicClock clock;
  const std::int64_t deadline = clock.now_ns() + 2'000'000;
  clock.sleep_until_ns(deadline);
  EXPECT_GE(clock.now_ns(), deadline);
  Clock& base = clock;
  const std::int64_t second_deadline = base.now_ns() + 1'000'000;
  base.sleep_until_ns(second_deadline);
  EXPECT_GE(base.now_ns(), second_deadline);
}

}  // namespace
}  // namespace trainer::core
