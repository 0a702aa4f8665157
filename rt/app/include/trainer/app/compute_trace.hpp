// The compute time of every cycle of a simulated-time run, and its per-cycle minimum over
// repeated runs of the same deterministic session (trainer --repeat N, issue 19).
//
// Why a per-cycle minimum: this VM's hypervisor takes a vCPU ~1,250 times a second for ~37 µs,
// so a 20 µs cycle is hit in ~2.5 % of the cycles whatever the code does, and the p99.9 of one
// run measures the VM. A simulated-time session is deterministic (same inputs, same contacts,
// same branches in every run), so cycle k costs the same compute in every run; an interrupt
// rarely hits the same cycle in all of them. The minimum over N runs of cycle k's time is that
// cycle's compute without the noise (up to cache effects), and its percentiles over the
// session are the compute distribution.
//
// CycleTimeTrace: one run's per-cycle times (ns, real monotonic clock), one column per
// quantity: the step (run_cycle, timed by the loop), each phase of the cycle (the stage
// runner's split) and each sub-stage (substage_timer.hpp). Sized on the setup path before
// arming; the RT thread only writes into it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <ostream>
#include <span>
#include <string>
#include <vector>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/stage_runner.hpp"

namespace trainer::app {

// Columns: step, the phases in cycle order, the sub-stages in cycle order.
inline constexpr std::size_t kStepColumn = 0;
inline constexpr std::size_t kFirstPhaseColumn = 1;
inline constexpr std::size_t kFirstSubstageColumn = kFirstPhaseColumn + kCyclePhaseCount;
inline constexpr std::size_t kComputeColumns = kFirstSubstageColumn + kSubstageCount;
const char* compute_column_name(std::size_t column) noexcept;

class CycleTimeTrace {
 public:
  // Setup path: room for `cycles` cycles, every value 0 (allocates only to grow).
  void prepare(std::size_t cycles);
  std::size_t cycles() const noexcept { return cycles_; }

  // The step column, for PeriodicLoop::set_step_trace.
  std::span<std::int64_t> step_ns() noexcept { return column_span(kStepColumn); }
  // RT path: cycle `cycle`'s phase times and sub-stage laps (ignored past the capacity).
  void record_stages(std::uint64_t cycle, const StageRunner& runner,
                     const SubstageTimer& laps) noexcept;

  std::span<const std::int64_t> column(std::size_t column) const noexcept {
    return {values_.data() + column * cycles_, cycles_};
  }
  // Keeps, per column and cycle, the smaller of this trace's value and `run`'s, over the
  // first `cycles` cycles (this trace is sized to them); the first fold (folds() == 0) copies.
  void fold_minimum(const CycleTimeTrace& run, std::size_t cycles);
  std::uint32_t folds() const noexcept { return folds_; }

 private:
  std::span<std::int64_t> column_span(std::size_t column) noexcept {
    return {values_.data() + column * cycles_, cycles_};
  }
  std::size_t cycles_ = 0;
  std::vector<std::int64_t> values_;  // column-major: column c at [c * cycles_, (c+1) * cycles_)
  std::uint32_t folds_ = 0;
};

// Exact order statistics of one column over the cycles (nearest rank: the p-quantile of n
// sorted values is the value at rank ceil(p·n)), in ns.
struct ComputeStatistics {
  std::string name;
  std::uint64_t count = 0;
  std::int64_t min_ns = 0;
  std::int64_t p50_ns = 0;
  std::int64_t p99_ns = 0;
  std::int64_t p99_9_ns = 0;
  std::int64_t max_ns = 0;
  double mean_ns = 0.0;
};
ComputeStatistics compute_statistics(std::string name, std::span<const std::int64_t> values);

// One run of a --repeat series.
struct ComputeRun {
  std::uint64_t cycles = 0;
  std::uint64_t final_state_hash = 0;
  double wall_time_s = 0.0;
  ComputeStatistics step;  // this run's own per-cycle step times, noise included
};

// The report's "compute" section (docs/report.md).
struct ComputeSummary {
  std::uint32_t runs = 0;      // complete runs folded into the minimum
  std::uint64_t cycles = 0;    // cycles of each run
  std::int64_t period_ns = 0;  // the loop's period (simulated)
  // Every run had the same cycle count, final state hash, latched faults and armed cycles;
  // otherwise `mismatch` says what differed first and the minima mean nothing.
  bool identical = true;
  std::string mismatch;
  ComputeStatistics step;                    // statistics of the per-cycle minimum
  std::vector<ComputeStatistics> stages;     // the stages the scene runs, in cycle order
  std::vector<ComputeStatistics> substages;  // the sub-stages of those stages
  std::vector<ComputeRun> per_run;
  // The per-cycle minimum itself (every column, `cycles` cycles), for --compute-csv.
  std::shared_ptr<const CycleTimeTrace> per_cycle_minimum;
};

// The per-cycle minimum as CSV: a header "cycle,step,hal_read,...,catheter_reactions" (the
// columns of the stages and sub-stages in `summary`), then one line per cycle, in ns.
void write_compute_csv(const ComputeSummary& summary, std::ostream& out);

// The summary of `minimum` (the fold of every run) for the columns the run used: the phases
// whose histograms in `app` have samples, the sub-stages likewise.
ComputeSummary summarize_compute(const CycleTimeTrace& minimum, std::size_t cycles,
                                 const AppStats& app);

}  // namespace trainer::app
