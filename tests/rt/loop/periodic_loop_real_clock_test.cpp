// PeriodicLoop on the real MonotonicClock. No timing bounds are asserted (this VM is noisy and
// not PREEMPT_RT); only properties that hold however late the wake-ups are: every cycle is
// recorded, deadlines stay on the period grid and increase, a wake is never before its
// deadline (absolute clock_nanosleep), and skipped periods match the gaps in the deadlines.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>

#include "trainer/core/clock.hpp"
#include "trainer/loop/periodic_loop.hpp"

namespace trainer::loop {
namespace {

constexpr std::size_t kCycles = 200;
constexpr std::int64_t kRealClockPeriodNs = 1'000'000;

class RecordingTask final : public CycleTask {
 public:
  core::Status run_cycle(const CycleTiming& timing) noexcept override {
    if (count_ < timings_.size()) timings_[count_++] = timing;
    return core::Status::ok();
  }
  void on_overrun_fault(std::uint32_t) noexcept override { ++fault_calls_; }

  std::size_t count() const { return count_; }
  const CycleTiming& timing(std::size_t i) const { return timings_[i]; }
  int fault_calls() const { return fault_calls_; }

 private:
  std::array<CycleTiming, kCycles> timings_{};
  std::size_t count_ = 0;
  int fault_calls_ = 0;
};

TEST(PeriodicLoopRealClock, TwoHundredCyclesAtOneMillisecondComplete) {
  core::MonotonicClock clock;
  RecordingTask task;
  PeriodicLoop loop(clock, LoopSettings{kRealClockPeriodNs, 0, kCycles});  // no fault: noise is allowed
  const std::atomic<bool> stop{false};
  const std::int64_t start_ns = clock.now_ns();
  loop.run(task, stop);
  const std::int64_t end_ns = clock.now_ns();

  const LoopStats& stats = loop.stats();
  ASSERT_EQ(task.count(), kCycles);
  EXPECT_EQ(stats.cycles, kCycles);
  EXPECT_EQ(stats.wake_latency.count(), kCycles);
  EXPECT_EQ(stats.step_time.count(), kCycles);
  EXPECT_EQ(stats.period.count(), kCycles - 1);
  EXPECT_EQ(task.fault_calls(), 0);
  EXPECT_FALSE(stats.overrun_fault);

  EXPECT_GT(task.timing(0).deadline_ns, start_ns);
  std::uint64_t grid_points_passed_over = 0;
  for (std::size_t i = 0; i < kCycles; ++i) {
    const CycleTiming& timing = task.timing(i);
    SCOPED_TRACE(i);
    EXPECT_EQ(timing.cycle_index, i);
    EXPECT_GE(timing.wake_ns, timing.deadline_ns);
    EXPECT_GT(timing.dt_s, 0.0);
    if (i == 0) continue;
    const std::int64_t step_ns = timing.deadline_ns - task.timing(i - 1).deadline_ns;
    ASSERT_GT(step_ns, 0);              // monotonic
    EXPECT_EQ(step_ns % kRealClockPeriodNs, 0);  // on the grid
    grid_points_passed_over += static_cast<std::uint64_t>(step_ns / kRealClockPeriodNs - 1);
  }
  EXPECT_EQ(grid_points_passed_over, stats.skipped_periods);
  // A run of kCycles periods cannot finish before the last deadline.
  EXPECT_GE(end_ns, task.timing(kCycles - 1).deadline_ns);
  EXPECT_GE(end_ns - start_ns, static_cast<std::int64_t>(kCycles) * kRealClockPeriodNs);
}

}  // namespace
}  // namespace trainer::loop
