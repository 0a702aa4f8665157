// The watchdog health decision: pings at half of WATCHDOG_USEC while the cycle counter
// advances; none while it is stalled, after an overrun fault, after the loop ended, or when
// the watchdog is off.
#include <gtest/gtest.h>

#include "trainer/appliance/watchdog_health.hpp"

namespace trainer::appliance {
namespace {

constexpr std::uint64_t kWatchdogUsec = 2'000'000;  // WatchdogSec=2
constexpr std::int64_t kTickNs = 33'000'000;        // the supervisor's period
constexpr std::int64_t kPeriodNs = 1'000'000;       // a 1 kHz loop

TEST(WatchdogHealth, HealthyLoopIsPingedAtHalfTheWatchdogPeriod) {
  WatchdogHealth health(kWatchdogUsec);
  EXPECT_EQ(health.ping_interval_ns(), 1'000'000'000);
  std::vector<std::int64_t> pings;
  for (std::int64_t now = 0; now <= 10'000'000'000; now += kTickNs) {
    const LoopObservation loop{static_cast<std::uint64_t>(now / kPeriodNs), false, false};
    if (health.should_ping(now, loop)) pings.push_back(now);
  }
  // The first tick sees cycle 0 (not started); the second pings; then one per interval, each
  // at the first tick at or after the interval (33 ms granularity).
  ASSERT_EQ(pings.size(), 10U);
  EXPECT_EQ(pings.front(), kTickNs);
  for (std::size_t k = 1; k < pings.size(); ++k) {
    const std::int64_t gap = pings[k] - pings[k - 1];
    EXPECT_GE(gap, 1'000'000'000);
    EXPECT_LT(gap, 1'000'000'000 + kTickNs);
  }
  EXPECT_EQ(health.pings(), 10U);
  EXPECT_EQ(health.health(), LoopHealth::healthy);
}

TEST(WatchdogHealth, StalledLoopIsNotPingedAndRecoversWhenItAdvancesAgain) {
  WatchdogHealth health(kWatchdogUsec);
  EXPECT_TRUE(health.should_ping(0, {100, false, false}));
  // The counter stays at 100 for three intervals: no ping, health says stalled.
  for (std::int64_t now = kTickNs; now < 3'000'000'000; now += kTickNs) {
    EXPECT_FALSE(health.should_ping(now, {100, false, false})) << now;
  }
  EXPECT_EQ(health.health(), LoopHealth::stalled);
  EXPECT_TRUE(health.should_ping(3'000'000'000, {101, false, false}));
  EXPECT_EQ(health.pings(), 2U);
}

TEST(WatchdogHealth, OverrunFaultAndFinishedLoopStopThePings) {
  WatchdogHealth health(kWatchdogUsec);
  EXPECT_TRUE(health.should_ping(0, {10, false, false}));
  EXPECT_FALSE(health.should_ping(1'000'000'000, {2000, true, false}));
  EXPECT_EQ(health.health(), LoopHealth::faulted);
  EXPECT_FALSE(health.should_ping(2'000'000'000, {3000, true, false}));
  WatchdogHealth ended(kWatchdogUsec);
  EXPECT_FALSE(ended.should_ping(0, {10, false, true}));
  EXPECT_EQ(ended.health(), LoopHealth::finished);
}

TEST(WatchdogHealth, NoPingsBeforeTheFirstCycleOrWithoutAWatchdog) {
  WatchdogHealth health(kWatchdogUsec);
  EXPECT_FALSE(health.should_ping(0, {0, false, false}));
  EXPECT_EQ(health.health(), LoopHealth::not_started);
  WatchdogHealth off(0);
  for (std::int64_t now = 0; now < 5'000'000'000; now += kTickNs) {
    EXPECT_FALSE(off.should_ping(now, {static_cast<std::uint64_t>(now), false, false}));
  }
}

TEST(WatchdogHealth, DoesNotPingFasterThanTheIntervalWhateverTheTickRate) {
  WatchdogHealth health(kWatchdogUsec);
  std::uint64_t cycle = 1;
  for (std::int64_t now = 0; now < 1'000'000'000; now += 1'000'000) {
    (void)health.should_ping(now, {cycle++, false, false});
  }
  EXPECT_EQ(health.pings(), 1U);
}

}  // namespace
}  // namespace trainer::appliance
