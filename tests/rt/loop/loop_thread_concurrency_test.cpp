// The loop on an RtThread with MonotonicClock, stopped by a flag set from the main thread: the
// shape of the app's haptic thread (run under TSan by the `concurrency` preset). Asserts only
// ordering facts, never durations: the loop stops, at most one cycle starts after the stop is
// visible to it, and the stats are complete and readable after join.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

#include "trainer/core/clock.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/loop/rt_thread.hpp"

namespace trainer::loop {
namespace {

class ProgressTask final : public CycleTask {
 public:
  explicit ProgressTask(const std::atomic<bool>& stop) : stop_(stop) {}

  core::Status run_cycle(const CycleTiming& timing) noexcept override {
    if (stop_.load(std::memory_order_acquire)) ++cycles_after_stop_seen_;
    last_index_ = timing.cycle_index;
    ++cycles_;  // plain counter: only read after join
    completed_.store(cycles_, std::memory_order_release);
    return core::Status::ok();
  }
  void on_overrun_fault(std::uint32_t) noexcept override {}

  std::uint64_t completed() const noexcept { return completed_.load(std::memory_order_acquire); }
  std::uint64_t cycles() const noexcept { return cycles_; }
  std::uint64_t cycles_after_stop_seen() const noexcept { return cycles_after_stop_seen_; }
  std::uint64_t last_index() const noexcept { return last_index_; }

 private:
  const std::atomic<bool>& stop_;
  std::atomic<std::uint64_t> completed_{0};
  std::uint64_t cycles_ = 0;
  std::uint64_t cycles_after_stop_seen_ = 0;
  std::uint64_t last_index_ = 0;
};

TEST(PeriodicLoopConcurrency, StopFlagFromMainThreadEndsTheLoopOnItsThread) {
  constexpr std::uint64_t kCyclesBeforeStop = 20;
  core::MonotonicClock clock;
  std::atomic<bool> stop{false};
  ProgressTask task(stop);
  PeriodicLoop loop(clock, LoopSettings{500'000, 0, 0});  // 2 kHz, until stop

  auto thread =
      RtThread::start([&] { loop.run(task, stop); }, RtThread::kDefaultStackBytes, "loop-test");
  ASSERT_TRUE(thread.has_value()) << thread.error().message;

  // Generous bound against a hang only (not a timing assertion): 60 s for 20 cycles.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (task.completed() < kCyclesBeforeStop && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const std::uint64_t completed_at_stop = task.completed();
  stop.store(true, std::memory_order_release);
  thread->join();

  EXPECT_GE(completed_at_stop, kCyclesBeforeStop);
  const LoopStats& stats = loop.stats();  // join() orders the loop's writes before this read
  EXPECT_EQ(stats.cycles, task.cycles());
  EXPECT_GE(stats.cycles, completed_at_stop);
  EXPECT_EQ(task.last_index() + 1, stats.cycles);
  EXPECT_EQ(stats.step_time.count(), stats.cycles);
  EXPECT_EQ(stats.period.count(), stats.cycles - 1);
  // The flag is checked before each sleep: once the loop can see it, at most the cycle that
  // was already past the check runs.
  EXPECT_LE(task.cycles_after_stop_seen(), 1u);
}

}  // namespace
}  // namespace trainer::loop
