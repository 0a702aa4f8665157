// The fixed-period cycle runner of the haptic thread: sleeps to absolute deadlines on a
// core::Clock, calls one CycleTask per period, applies the overrun policy below and keeps
// timing statistics. Owns no thread: run() executes on the caller's thread (an RtThread after
// apply_rt_settings in the app; the test thread with a ManualClock in tests).
//
// Overrun policy
// --------------
// Cycle n is scheduled at deadline_n and wakes at wake_n >= deadline_n. It OVERRUNS when
// run_cycle ends after the next deadline: end_ns > deadline_n + period_ns (ending exactly on
// the next deadline is on time). Then:
//   * the overrun is counted and the streak grows; an on-time cycle resets the streak to 0;
//   * when the streak reaches overrun_streak_limit, task.on_overrun_fault(streak) is called
//     once, in that same cycle, right after its run_cycle (the fault latches for the rest of
//     the run: stats().overrun_fault, overrun_fault_cycle). The loop keeps running so the task
//     keeps its outputs at zero and the statistics continue;
//   * no catch-up burst: the next deadline is the first one on the original grid
//     (deadline_n + k * period_ns, k >= 1) strictly after end_ns; the k - 1 grid points
//     passed over are counted in skipped_periods when the next cycle runs (a run that ends
//     right after an overrun skipped nothing: skipped_periods always equals the gaps between
//     the deadlines the task saw);
//   * the next cycle runs with the measured dt (wake to wake), not the nominal period, so
//     integrators in the task see the time that really passed.
// A non-ok Status from run_cycle is only counted (cycle_errors): the task owns its faults.
//
// Step time
// ---------
// step_time is run_cycle's duration on the loop's clock, unless a separate step clock is set
// (set_step_clock): then on that one. The trainer sets the real monotonic clock in simulated
// time, where the loop's clock is a manual clock that does not move during a cycle, so the
// step time is the cycle's real compute time there too; deadlines, overruns, wake-up latency
// and period stay on the loop's clock (deterministic: 0 latency, the nominal period, no
// overrun in simulated time).
#pragma once

#include <atomic>
#include <cstdint>
#include <span>

#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/histogram.hpp"
#include "trainer/core/status.hpp"

namespace trainer::loop {

// What the loop tells the task about the current cycle. All times are absolute on the
// loop's clock, in nanoseconds.
struct CycleTiming {
  std::uint64_t cycle_index;     // 0-based
  std::int64_t deadline_ns;      // scheduled wake-up
  std::int64_t wake_ns;          // actual wake-up
  double dt_s;                   // measured time since the previous cycle's wake (nominal
                                 // period on cycle 0); after an overrun it is the late interval
  std::uint32_t overrun_streak;  // consecutive overruns up to and including the previous cycle
};

// The work done once per period. Both calls are on the RT thread after arming: noexcept, no
// heap, no locks, no blocking syscalls beyond the task's own bounded I/O.
class CycleTask {
 public:
  virtual core::Status run_cycle(const CycleTiming& timing) noexcept = 0;
  // Called in the same cycle the overrun streak reaches the limit, after that cycle's
  // run_cycle: the task zeroes its outputs and latches a fault (the loop keeps running so the
  // outputs stay at zero and stats continue). Called at most once per run().
  virtual void on_overrun_fault(std::uint32_t streak) noexcept = 0;

 protected:
  ~CycleTask() = default;
};

struct LoopSettings {
  std::int64_t period_ns;              // > 0
  std::uint32_t overrun_streak_limit;  // consecutive overruns that fault; 0 disables the fault
  std::uint64_t max_cycles;            // 0 = until stop
};

// Setup-path check of LoopSettings (period_ns > 0); the error names the field and its range.
core::Expected<void> validate(const LoopSettings& settings);

struct LoopStats {
  std::uint64_t cycles = 0;           // run_cycle calls
  std::uint64_t overruns = 0;         // cycles that ended after the next deadline
  std::uint64_t skipped_periods = 0;  // grid deadlines passed over after overruns
  std::uint64_t cycle_errors = 0;     // run_cycle calls that returned a non-ok Status
  std::uint32_t longest_overrun_streak = 0;
  bool overrun_fault = false;             // the streak limit was reached during this run
  std::uint64_t overrun_fault_cycle = 0;  // cycle_index in which it was reached
  core::LatencyHistogram wake_latency;    // wake_ns - deadline_ns
  core::LatencyHistogram step_time;       // run_cycle's duration (on the step clock if set)
  core::LatencyHistogram period;          // wake_ns - previous wake_ns (cycle 1 onward)
};

class PeriodicLoop {
 public:
  // The clock must outlive the loop. Settings are taken as given; check them with validate()
  // on the setup path (run() with period_ns <= 0 returns at once with zero cycles).
  PeriodicLoop(core::Clock& clock, LoopSettings settings) noexcept;

  // Runs until max_cycles cycles ran or `stop` is seen true (checked once per cycle, before
  // sleeping, so at most one more cycle runs after another thread sets it). The first
  // deadline is clock.now_ns() + period_ns. noexcept, no heap, no syscalls but the clock's.
  // Resets stats() at the start; stats() holds the results when it returns. Uses about
  // sizeof(LoopStats) (~30 KiB) of stack once at entry, to reset the statistics.
  void run(CycleTask& task, const std::atomic<bool>& stop) noexcept;

  // Setup path, before run(): time run_cycle on `clock` instead of the loop's clock (nullptr:
  // the loop's clock). The clock must outlive the loop's runs.
  void set_step_clock(core::Clock* clock) noexcept { step_clock_ = clock; }
  // Setup path, before run(): every cycle's step time (ns) also goes to step_trace[cycle_index]
  // while cycle_index < step_trace.size() (trainer --repeat's per-cycle record). The buffer
  // must outlive the loop's runs; nothing is allocated.
  void set_step_trace(std::span<std::int64_t> step_trace) noexcept { step_trace_ = step_trace; }

  // Read it after run() returned (or from the thread running it): not synchronised.
  const LoopStats& stats() const noexcept { return stats_; }
  const LoopSettings& settings() const noexcept { return settings_; }

 private:
  core::Clock& clock_;
  LoopSettings settings_;
  core::Clock* step_clock_ = nullptr;
  std::span<std::int64_t> step_trace_;
  LoopStats stats_{};
};

}  // namespace trainer::loop
