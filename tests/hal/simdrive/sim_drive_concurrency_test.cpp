// SimDriveBus::post() from another thread while the polling thread runs SYNC cycles (run under
// TSan by the tsan preset): every posted fault is either applied by a poll or counted as refused.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "simdrive_test_support.hpp"

namespace trainer::hal::simdrive {
namespace {

using namespace test_support;  // NOLINT: test fixtures

TEST(SimDriveBusConcurrency, FaultsPostedWhileThePollingThreadRunsAreAllAccountedFor) {
  DriveHarness h;
  (void)h.power_on();
  (void)h.exchange({nmt_frame(kNmtStart, 0)});
  constexpr int kPosts = 2000;
  std::atomic<int> accepted{0};
  std::atomic<bool> done{false};
  std::thread poster([&] {
    const FaultSpec jump = *parse_fault_spec("encoder_jump:node=2,counts=1");
    for (int i = 0; i < kPosts; ++i) {
      if (h.bus().post(jump)) accepted.fetch_add(1, std::memory_order_relaxed);
      if (i % 64 == 0) std::this_thread::yield();
    }
    done.store(true, std::memory_order_release);
  });
  int cycles = 0;
  while (!done.load(std::memory_order_acquire) || cycles < 10) {
    (void)h.sync();
    ++cycles;
  }
  poster.join();
  (void)h.poll();  // the last ones
  const std::uint64_t applied = h.bus().node_stats(1).faults_injected;
  EXPECT_EQ(applied, static_cast<std::uint64_t>(accepted.load()));
  EXPECT_EQ(applied + h.bus().stats().faults_refused, static_cast<std::uint64_t>(kPosts));
  EXPECT_GT(applied, 0U);
}

}  // namespace
}  // namespace trainer::hal::simdrive
