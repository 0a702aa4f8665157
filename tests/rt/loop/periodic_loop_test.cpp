// PeriodicLoop on a ManualClock: deadlines, dt, overrun policy, streak fault, stop/max_cycles,
// error counting, statistics and "no heap in run()". The task moves the clock by a scripted
// step time per cycle, so every expected value below is exact arithmetic, not a measurement.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/core/status.hpp"
#include "trainer/loop/periodic_loop.hpp"

namespace trainer::loop {
namespace {

constexpr std::int64_t kPeriodNs = 1'000'000;  // 1 kHz
constexpr double kPeriodS = 1e-3;
constexpr std::int64_t kStartNs = 5'000'000'000;  // arbitrary non-zero epoch

struct FaultCall {
  std::uint32_t streak;
  std::uint64_t during_cycle;  // cycle_index of the run_cycle that preceded the call
};

// Advances the clock by step_ns_by_cycle[i] in cycle i (default_step_ns past the script's end),
// records what the loop passed in, and runs an optional per-cycle hook (stop flag, wake
// latency, error returns). Recording stops at record_capacity so a run never reallocates.
class ScriptedTask final : public CycleTask {
 public:
  using Hook = std::function<core::Status(const CycleTiming&)>;

  ScriptedTask(core::ManualClock& clock, std::int64_t default_step_ns,
               std::vector<std::int64_t> step_ns_by_cycle = {}, std::size_t record_capacity = 1024)
      : clock_(clock),
        default_step_ns_(default_step_ns),
        step_ns_by_cycle_(std::move(step_ns_by_cycle)),
        record_capacity_(record_capacity) {
    timings_.reserve(record_capacity_);
    fault_calls_.reserve(16);
  }

  void set_hook(Hook hook) { hook_ = std::move(hook); }

  core::Status run_cycle(const CycleTiming& timing) noexcept override {
    last_cycle_index_ = timing.cycle_index;
    if (timings_.size() < record_capacity_) timings_.push_back(timing);
    const std::size_t index = static_cast<std::size_t>(timing.cycle_index);
    clock_.advance_ns(index < step_ns_by_cycle_.size() ? step_ns_by_cycle_[index]
                                                       : default_step_ns_);
    return hook_ ? hook_(timing) : core::Status::ok();
  }

  void on_overrun_fault(std::uint32_t streak) noexcept override {
    if (fault_calls_.size() < fault_calls_.capacity()) {
      fault_calls_.push_back({streak, last_cycle_index_});
    }
  }

  const std::vector<CycleTiming>& timings() const { return timings_; }
  const std::vector<FaultCall>& fault_calls() const { return fault_calls_; }

 private:
  core::ManualClock& clock_;
  std::int64_t default_step_ns_;
  std::vector<std::int64_t> step_ns_by_cycle_;
  std::size_t record_capacity_;
  Hook hook_;
  std::uint64_t last_cycle_index_ = 0;
  std::vector<CycleTiming> timings_;
  std::vector<FaultCall> fault_calls_;
};

LoopSettings settings(std::uint64_t max_cycles, std::uint32_t streak_limit = 3) {
  return LoopSettings{kPeriodNs, streak_limit, max_cycles};
}

TEST(PeriodicLoop, OnTimeCyclesHaveNoOverrunsAndNominalDt) {
  constexpr std::int64_t kWakeLatencyNs = 7'000;
  constexpr std::int64_t kStepNs = 300'000;
  core::ManualClock clock(kStartNs);
  clock.set_wake_latency_ns(kWakeLatencyNs);
  ScriptedTask task(clock, kStepNs);
  PeriodicLoop loop(clock, settings(50));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  const LoopStats& stats = loop.stats();
  EXPECT_EQ(stats.cycles, 50u);
  EXPECT_EQ(stats.overruns, 0u);
  EXPECT_EQ(stats.skipped_periods, 0u);
  EXPECT_EQ(stats.cycle_errors, 0u);
  EXPECT_EQ(stats.longest_overrun_streak, 0u);
  EXPECT_FALSE(stats.overrun_fault);
  EXPECT_TRUE(task.fault_calls().empty());

  ASSERT_EQ(task.timings().size(), 50u);
  for (std::size_t i = 0; i < task.timings().size(); ++i) {
    const CycleTiming& timing = task.timings()[i];
    SCOPED_TRACE(i);
    EXPECT_EQ(timing.cycle_index, i);
    // First deadline = start + period; then one period apart on the grid.
    EXPECT_EQ(timing.deadline_ns, kStartNs + static_cast<std::int64_t>(i + 1) * kPeriodNs);
    EXPECT_EQ(timing.wake_ns - timing.deadline_ns, kWakeLatencyNs);
    EXPECT_DOUBLE_EQ(timing.dt_s, kPeriodS);
    EXPECT_EQ(timing.overrun_streak, 0u);
  }

  EXPECT_EQ(stats.wake_latency.count(), 50u);
  EXPECT_EQ(stats.wake_latency.min_ns(), kWakeLatencyNs);
  EXPECT_EQ(stats.wake_latency.max_ns(), kWakeLatencyNs);
  EXPECT_EQ(stats.step_time.min_ns(), kStepNs);
  EXPECT_EQ(stats.step_time.max_ns(), kStepNs);
  EXPECT_EQ(stats.period.count(), 49u);  // measured from cycle 1 onward
  EXPECT_EQ(stats.period.min_ns(), kPeriodNs);
  EXPECT_EQ(stats.period.max_ns(), kPeriodNs);
}

TEST(PeriodicLoop, StepEndingExactlyOnNextDeadlineIsOnTime) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, kPeriodNs);  // ends exactly at deadline + period
  PeriodicLoop loop(clock, settings(10));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  EXPECT_EQ(loop.stats().overruns, 0u);
  EXPECT_EQ(loop.stats().skipped_periods, 0u);
  ASSERT_EQ(task.timings().size(), 10u);
  for (std::size_t i = 1; i < task.timings().size(); ++i) {
    EXPECT_EQ(task.timings()[i].deadline_ns - task.timings()[i - 1].deadline_ns, kPeriodNs);
    EXPECT_DOUBLE_EQ(task.timings()[i].dt_s, kPeriodS);
  }
}

TEST(PeriodicLoop, LongStepOverrunsOnceSkipsMissedDeadlinesWithoutCatchUp) {
  constexpr std::int64_t kShortStepNs = 100'000;
  constexpr std::int64_t kLongStepNs = 3'500'000;  // 3.5 periods
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, kShortStepNs, {kShortStepNs, kShortStepNs, kLongStepNs});
  PeriodicLoop loop(clock, settings(8));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  const LoopStats& stats = loop.stats();
  EXPECT_EQ(stats.cycles, 8u);
  EXPECT_EQ(stats.overruns, 1u);
  EXPECT_EQ(stats.longest_overrun_streak, 1u);
  // Cycle 2 starts at grid point 3 and ends at 3 + 3.5: grid points 4, 5 and 6 are passed
  // over, the next deadline is 7 (the first strictly after the end).
  EXPECT_EQ(stats.skipped_periods, 3u);
  EXPECT_FALSE(stats.overrun_fault);

  const auto& timings = task.timings();
  ASSERT_EQ(timings.size(), 8u);
  const std::int64_t expected_grid_points[] = {1, 2, 3, 7, 8, 9, 10, 11};
  for (std::size_t i = 0; i < timings.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(timings[i].deadline_ns, kStartNs + expected_grid_points[i] * kPeriodNs);
    EXPECT_EQ(timings[i].wake_ns, timings[i].deadline_ns);          // no injected latency
    EXPECT_EQ((timings[i].deadline_ns - kStartNs) % kPeriodNs, 0);  // stays on the grid
  }
  // The cycle after the overrun sees the real interval since the previous wake (3 -> 7).
  EXPECT_DOUBLE_EQ(timings[3].dt_s, 4 * kPeriodS);
  EXPECT_EQ(timings[3].overrun_streak, 1u);
  EXPECT_EQ(timings[4].overrun_streak, 0u);  // reset by the on-time cycle 3
  EXPECT_DOUBLE_EQ(timings[4].dt_s, kPeriodS);
  EXPECT_EQ(stats.period.max_ns(), 4 * kPeriodNs);
  EXPECT_EQ(stats.step_time.max_ns(), kLongStepNs);
}

TEST(PeriodicLoop, StepEndingExactlyOnALaterGridPointSkipsIt) {
  // Ends at deadline + 2 periods: an overrun; "strictly after" makes the next deadline
  // deadline + 3 periods, with 2 grid points skipped.
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 0, {2 * kPeriodNs});
  PeriodicLoop loop(clock, settings(2));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  EXPECT_EQ(loop.stats().overruns, 1u);
  EXPECT_EQ(loop.stats().skipped_periods, 2u);
  ASSERT_EQ(task.timings().size(), 2u);
  EXPECT_EQ(task.timings()[1].deadline_ns, kStartNs + 4 * kPeriodNs);
}

TEST(PeriodicLoop, OverrunInTheLastCycleSkipsNothing) {
  // The run ends after cycle 1's 2.5-period step: an overrun, but no later deadline was passed
  // over by a cycle that ran, so the deadlines the task saw have no gap and nothing is skipped.
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 0, {0, 2'500'000});
  PeriodicLoop loop(clock, settings(2));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  EXPECT_EQ(loop.stats().overruns, 1u);
  EXPECT_EQ(loop.stats().skipped_periods, 0u);
  ASSERT_EQ(task.timings().size(), 2u);
  EXPECT_EQ(task.timings()[1].deadline_ns - task.timings()[0].deadline_ns, kPeriodNs);
}

TEST(PeriodicLoop, LateWakeWithShortStepIsAnOverrun) {
  // The policy judges the end of the step against the next deadline, however the time was
  // lost: a 0.95-period wake latency plus a 0.1-period step ends 1.05 periods after deadline.
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 100'000);
  task.set_hook([&clock](const CycleTiming& timing) {
    clock.set_wake_latency_ns(timing.cycle_index == 0 ? 950'000 : 0);  // for the next wake
    return core::Status::ok();
  });
  clock.set_wake_latency_ns(950'000);  // the first wake
  PeriodicLoop loop(clock, settings(3));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  EXPECT_EQ(loop.stats().overruns, 2u);  // cycles 0 and 1 woke 0.95 periods late
  EXPECT_EQ(loop.stats().skipped_periods, 2u);
  EXPECT_EQ(loop.stats().wake_latency.max_ns(), 950'000);
  ASSERT_EQ(task.timings().size(), 3u);
  EXPECT_EQ(task.timings()[1].deadline_ns, kStartNs + 3 * kPeriodNs);
  EXPECT_EQ(task.timings()[2].deadline_ns, kStartNs + 5 * kPeriodNs);
}

TEST(PeriodicLoop, StreakOfLimitMinusOneDoesNotFaultLimitFaultsOnceInThatCycle) {
  constexpr std::int64_t kOnTimeNs = 200'000;
  constexpr std::int64_t kOverrunNs = 1'500'000;
  constexpr std::uint32_t kLimit = 3;
  // cycle:    0        1        2        3        4        5        6        7        8
  //           on time  overrun  overrun  on time  overrun  overrun  overrun  overrun  on time
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, kOnTimeNs,
                    {kOnTimeNs, kOverrunNs, kOverrunNs, kOnTimeNs, kOverrunNs, kOverrunNs,
                     kOverrunNs, kOverrunNs, kOnTimeNs});
  PeriodicLoop loop(clock, settings(11, kLimit));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  const LoopStats& stats = loop.stats();
  EXPECT_EQ(stats.cycles, 11u);
  EXPECT_EQ(stats.overruns, 6u);
  EXPECT_EQ(stats.skipped_periods, 6u);  // each 1.5-period step skips one grid point
  EXPECT_EQ(stats.longest_overrun_streak, 4u);
  EXPECT_TRUE(stats.overrun_fault);
  EXPECT_EQ(stats.overrun_fault_cycle, 6u);  // third consecutive overrun of the second streak

  ASSERT_EQ(task.fault_calls().size(), 1u);  // latched: not repeated at streak 4
  EXPECT_EQ(task.fault_calls()[0].streak, kLimit);
  EXPECT_EQ(task.fault_calls()[0].during_cycle, 6u);

  const auto& timings = task.timings();
  ASSERT_EQ(timings.size(), 11u);
  const std::uint32_t expected_streak_seen[] = {0, 0, 1, 2, 0, 1, 2, 3, 4, 0, 0};
  for (std::size_t i = 0; i < timings.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(timings[i].overrun_streak, expected_streak_seen[i]);
  }
}

TEST(PeriodicLoop, StreakLimitZeroNeverFaults) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 2'500'000);  // every cycle overruns
  PeriodicLoop loop(clock, settings(20, 0));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().overruns, 20u);
  EXPECT_EQ(loop.stats().longest_overrun_streak, 20u);
  EXPECT_FALSE(loop.stats().overrun_fault);
  EXPECT_TRUE(task.fault_calls().empty());
}

TEST(PeriodicLoop, MaxCyclesIsHonoured) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 10'000);
  PeriodicLoop loop(clock, settings(17));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().cycles, 17u);
  ASSERT_EQ(task.timings().size(), 17u);
  EXPECT_EQ(task.timings().back().cycle_index, 16u);
  // The loop returns right after the last cycle: no trailing sleep to a further deadline.
  EXPECT_EQ(clock.now_ns(), kStartNs + 17 * kPeriodNs + 10'000);
}

TEST(PeriodicLoop, StopFlagIsCheckedBeforeEachSleep) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 10'000);
  std::atomic<bool> stop{false};
  task.set_hook([&stop](const CycleTiming& timing) {
    if (timing.cycle_index == 5) stop.store(true, std::memory_order_release);
    return core::Status::ok();
  });
  PeriodicLoop loop(clock, settings(0));  // until stop
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().cycles, 6u);  // cycles 0..5, then the check before sleeping stops it
  EXPECT_EQ(task.timings().size(), 6u);
}

TEST(PeriodicLoop, StopAlreadySetRunsNoCycleAndResetsStats) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 10'000);
  PeriodicLoop loop(clock, settings(5));
  std::atomic<bool> stop{false};
  loop.run(task, stop);
  ASSERT_EQ(loop.stats().cycles, 5u);

  stop.store(true);
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().cycles, 0u);
  EXPECT_EQ(loop.stats().step_time.count(), 0u);
  EXPECT_EQ(task.timings().size(), 5u);  // no new run_cycle call
}

TEST(PeriodicLoop, NonOkStatusIsCountedAndTheLoopContinues) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 10'000);
  task.set_hook([](const CycleTiming& timing) {
    const bool fail = timing.cycle_index == 2 || timing.cycle_index == 5 || timing.cycle_index == 7;
    return fail ? core::Status(core::StatusCode::io_error, "scripted failure") : core::Status::ok();
  });
  PeriodicLoop loop(clock, settings(10));
  const std::atomic<bool> stop{false};
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().cycles, 10u);
  EXPECT_EQ(loop.stats().cycle_errors, 3u);
  EXPECT_FALSE(loop.stats().overrun_fault);
}

TEST(PeriodicLoop, HistogramsHoldAKnownSequence) {
  // Step times 1, 2, ..., 100 us; wake latencies (i mod 10) us. Period 1 s so nothing overruns.
  constexpr std::int64_t kLongPeriodNs = 1'000'000'000;
  std::vector<std::int64_t> steps;
  for (std::int64_t i = 1; i <= 100; ++i) steps.push_back(i * 1'000);
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 0, steps);
  task.set_hook([&clock](const CycleTiming& timing) {
    clock.set_wake_latency_ns(static_cast<std::int64_t>((timing.cycle_index + 1) % 10) * 1'000);
    return core::Status::ok();
  });
  PeriodicLoop loop(clock, LoopSettings{kLongPeriodNs, 3, 100});
  const std::atomic<bool> stop{false};
  loop.run(task, stop);

  const core::LatencyHistogram& step = loop.stats().step_time;
  ASSERT_EQ(step.count(), 100u);
  EXPECT_EQ(step.min_ns(), 1'000);
  EXPECT_EQ(step.max_ns(), 100'000);
  EXPECT_DOUBLE_EQ(step.mean_ns(), 50'500.0);
  // Percentiles are the upper edge of the holding bin: exact value .. +1/32 above it.
  const std::int64_t p50 = step.percentile_ns(0.50);
  EXPECT_GE(p50, 50'000);
  EXPECT_LE(p50, 50'000 + 50'000 / 32);
  const std::int64_t p90 = step.percentile_ns(0.90);
  EXPECT_GE(p90, 90'000);
  EXPECT_LE(p90, 90'000 + 90'000 / 32);
  EXPECT_EQ(step.percentile_ns(1.0), 100'000);  // clamped to the exact maximum

  const core::LatencyHistogram& latency = loop.stats().wake_latency;
  ASSERT_EQ(latency.count(), 100u);
  EXPECT_EQ(latency.min_ns(), 0);
  EXPECT_EQ(latency.max_ns(), 9'000);
  EXPECT_DOUBLE_EQ(latency.mean_ns(), 4'500.0);
  // Ten samples of each of 0..9 us: the 50th sample is 4 us, the 95th is 9 us.
  EXPECT_GE(latency.percentile_ns(0.50), 4'000);
  EXPECT_LT(latency.percentile_ns(0.50), 5'000);
  EXPECT_EQ(latency.percentile_ns(0.95), 9'000);

  // Wake to wake: one period plus the change in latency between consecutive wakes.
  const core::LatencyHistogram& period = loop.stats().period;
  EXPECT_EQ(period.count(), 99u);
  EXPECT_EQ(period.min_ns(), kLongPeriodNs - 9'000);  // latency 9 us -> 0 us
  EXPECT_EQ(period.max_ns(), kLongPeriodNs + 1'000);
}

// A separate step clock (the trainer's real clock in simulated time): step_time and the step
// trace come from it; deadlines and overruns stay on the loop's clock.
class TwoClockTask final : public CycleTask {
 public:
  TwoClockTask(core::ManualClock& loop_clock, core::ManualClock& step_clock)
      : loop_clock_(loop_clock), step_clock_(step_clock) {}
  core::Status run_cycle(const CycleTiming& timing) noexcept override {
    step_clock_.advance_ns(static_cast<std::int64_t>(timing.cycle_index + 1) * 10'000);
    // The loop's clock overruns in cycle 1 only (2.5 periods).
    if (timing.cycle_index == 1) loop_clock_.advance_ns(kPeriodNs * 5 / 2);
    return core::Status::ok();
  }
  void on_overrun_fault(std::uint32_t /*streak*/) noexcept override {}

 private:
  core::ManualClock& loop_clock_;
  core::ManualClock& step_clock_;
};

TEST(PeriodicLoop, AStepClockTimesTheStepAndFillsTheTrace) {
  core::ManualClock clock(kStartNs);
  core::ManualClock step_clock(0);
  TwoClockTask task(clock, step_clock);
  PeriodicLoop loop(clock, settings(5));
  loop.set_step_clock(&step_clock);
  std::vector<std::int64_t> trace(3, -1);
  loop.set_step_trace(trace);
  const std::atomic<bool> stop{false};
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().cycles, 5U);
  EXPECT_EQ(loop.stats().overruns, 1U);  // on the loop's clock
  EXPECT_EQ(loop.stats().skipped_periods, 2U);
  const core::LatencyHistogram& step = loop.stats().step_time;
  EXPECT_EQ(step.count(), 5U);
  EXPECT_EQ(step.min_ns(), 10'000);  // the step clock's, not the loop clock's 2.5 periods
  EXPECT_EQ(step.max_ns(), 50'000);
  EXPECT_EQ(trace, (std::vector<std::int64_t>{10'000, 20'000, 30'000}));  // cycles 3, 4: no room

  // Without a step clock the trace holds the loop clock's step (0 here but in cycle 1).
  PeriodicLoop plain(clock, settings(3));
  std::vector<std::int64_t> plain_trace(3, -1);
  plain.set_step_trace(plain_trace);
  plain.run(task, stop);
  EXPECT_EQ(plain_trace, (std::vector<std::int64_t>{0, kPeriodNs * 5 / 2, 0}));
}

TEST(PeriodicLoop, RunMakesNoHeapAllocationsOver100000Cycles) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  core::ManualClock clock(kStartNs);
  // Mixed on-time and overrunning steps so every branch of the policy runs.
  ScriptedTask task(clock, 400'000, {}, /*record_capacity=*/0);
  task.set_hook([&clock](const CycleTiming& timing) {
    if (timing.cycle_index % 1000 == 999) clock.advance_ns(2'000'000);
    return timing.cycle_index % 97 == 0 ? core::Status(core::StatusCode::timeout, "scripted")
                                        : core::Status::ok();
  });
  PeriodicLoop loop(clock, settings(100'000, 5));
  const std::atomic<bool> stop{false};

  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  loop.run(task, stop);
  core::alloc::end_counting_this_thread();
  const std::uint64_t after = core::alloc::counted_allocations();

  EXPECT_EQ(after - before, 0u);
  EXPECT_EQ(loop.stats().cycles, 100'000u);
  EXPECT_EQ(loop.stats().overruns, 100u);
  EXPECT_EQ(loop.stats().cycle_errors, 1031u);  // multiples of 97 below 100000, and 0
}

// Negative control for the test above: an allocating task is counted, so a zero count there
// means the loop really did not allocate.
class AllocatingTask final : public CycleTask {
 public:
  core::Status run_cycle(const CycleTiming& timing) noexcept override {
    values_.push_back(timing.cycle_index);  // grows: allocates on some cycles
    return core::Status::ok();
  }
  void on_overrun_fault(std::uint32_t) noexcept override {}
  std::size_t size() const { return values_.size(); }

 private:
  std::vector<std::uint64_t> values_;
};

TEST(PeriodicLoop, AllocationCounterSeesAnAllocatingTask) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  core::ManualClock clock(kStartNs);
  AllocatingTask task;
  PeriodicLoop loop(clock, settings(100));
  const std::atomic<bool> stop{false};
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  loop.run(task, stop);
  core::alloc::end_counting_this_thread();
  EXPECT_GT(core::alloc::counted_allocations() - before, 0u);
  EXPECT_EQ(task.size(), 100u);
}

TEST(PeriodicLoop, NonPositivePeriodRunsNothingAndValidateNamesTheField) {
  core::ManualClock clock(kStartNs);
  ScriptedTask task(clock, 10'000);
  PeriodicLoop loop(clock, LoopSettings{0, 3, 10});
  const std::atomic<bool> stop{false};
  loop.run(task, stop);
  EXPECT_EQ(loop.stats().cycles, 0u);
  EXPECT_TRUE(task.timings().empty());

  const core::Expected<void> bad = validate(LoopSettings{-5, 3, 10});
  ASSERT_FALSE(bad.has_value());
  EXPECT_NE(bad.error().message.find("period_ns = -5"), std::string::npos);
  EXPECT_TRUE(validate(LoopSettings{kPeriodNs, 3, 10}).has_value());
}

}  // namespace
}  // namespace trainer::loop
