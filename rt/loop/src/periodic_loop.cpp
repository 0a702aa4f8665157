// PeriodicLoop: the deadline arithmetic and overrun policy documented in periodic_loop.hpp.
#include "trainer/loop/periodic_loop.hpp"

#include <algorithm>
#include <string>

namespace trainer::loop {

namespace {
constexpr double kSecondsPerNanosecond = 1e-9;
}  // namespace

core::Expected<void> validate(const LoopSettings& settings) {
  if (settings.period_ns <= 0) {
    return core::make_error("loop settings: period_ns = " + std::to_string(settings.period_ns) +
                            ": expected a period > 0 nanoseconds");
  }
  return {};
}

PeriodicLoop::PeriodicLoop(core::Clock& clock, LoopSettings settings) noexcept
    : clock_(clock), settings_(settings) {}

void PeriodicLoop::run(CycleTask& task, const std::atomic<bool>& stop) noexcept {
  stats_ = LoopStats{};
  const std::int64_t period_ns = settings_.period_ns;
  if (period_ns <= 0) return;
  const double nominal_dt_s = static_cast<double>(period_ns) * kSecondsPerNanosecond;

  std::int64_t deadline_ns = clock_.now_ns() + period_ns;
  std::int64_t previous_wake_ns = 0;
  std::uint32_t overrun_streak = 0;
  // Grid points an overrun passed over count as skipped once the cycle after them runs; a run
  // that ends (stop or max_cycles) right after an overrun skipped nothing, it just ended.
  std::uint64_t pending_skipped = 0;

  for (std::uint64_t cycle_index = 0;
       settings_.max_cycles == 0 || cycle_index < settings_.max_cycles; ++cycle_index) {
    // Acquire pairs with the setter's store so anything it wrote before stopping is visible.
    if (stop.load(std::memory_order_acquire)) break;
    stats_.skipped_periods += pending_skipped;
    pending_skipped = 0;

    clock_.sleep_until_ns(deadline_ns);
    const std::int64_t wake_ns = clock_.now_ns();
    const CycleTiming timing{
        cycle_index, deadline_ns, wake_ns,
        cycle_index == 0 ? nominal_dt_s
                         : static_cast<double>(wake_ns - previous_wake_ns) * kSecondsPerNanosecond,
        overrun_streak};

    const std::int64_t step_start_ns = step_clock_ != nullptr ? step_clock_->now_ns() : wake_ns;
    const core::Status status = task.run_cycle(timing);
    const std::int64_t step_end_ns = step_clock_ != nullptr ? step_clock_->now_ns() : 0;
    const std::int64_t end_ns = clock_.now_ns();
    const std::int64_t step_ns =
        step_clock_ != nullptr ? step_end_ns - step_start_ns : end_ns - wake_ns;

    ++stats_.cycles;
    if (!status.is_ok()) ++stats_.cycle_errors;
    stats_.wake_latency.record(wake_ns - deadline_ns);
    stats_.step_time.record(step_ns);
    if (cycle_index < step_trace_.size()) step_trace_[cycle_index] = step_ns;
    if (cycle_index > 0) stats_.period.record(wake_ns - previous_wake_ns);

    const std::int64_t late_ns = end_ns - deadline_ns;
    if (late_ns > period_ns) {
      ++stats_.overruns;
      ++overrun_streak;
      stats_.longest_overrun_streak = std::max(stats_.longest_overrun_streak, overrun_streak);
      if (!stats_.overrun_fault && settings_.overrun_streak_limit != 0 &&
          overrun_streak >= settings_.overrun_streak_limit) {
        stats_.overrun_fault = true;
        stats_.overrun_fault_cycle = cycle_index;
        task.on_overrun_fault(overrun_streak);
      }
      // end_ns lies in (deadline + p * period, deadline + (p + 1) * period] with
      // p = late_ns / period >= 1; the first grid point strictly after it is p + 1 periods on,
      // and the p grid points in between are skipped.
      const std::int64_t periods_passed = late_ns / period_ns;
      pending_skipped = static_cast<std::uint64_t>(periods_passed);
      deadline_ns += (periods_passed + 1) * period_ns;
    } else {
      overrun_streak = 0;
      deadline_ns += period_ns;
    }
    previous_wake_ns = wake_ns;
  }
}

}  // namespace trainer::loop
