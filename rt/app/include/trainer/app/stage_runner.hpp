// The cycle as a list (shared/STYLE.md, "The cycle as a list"): the app registers, once at
// configure time, the stages a scene needs in the order of shared/DESIGN.md's "One cycle";
// run() calls each with the cycle's frame and times it into its phase's histogram. A stage
// never calls another; what one stage leaves for the next is in the CycleFrame.
//
// Timing uses the clock given at construction (the trainer gives the real monotonic clock, so
// the split means the same in simulated time); one clock read per stage boundary. The same
// read marks the start of the stage for its sub-stage laps (AppStats::laps, substage_timer.hpp),
// which use the same clock.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/cycle_frame.hpp"
#include "trainer/core/clock.hpp"

namespace trainer::app {

class CycleStage {
 public:
  virtual ~CycleStage() = default;
  // RT path: noexcept, no heap, no blocking beyond the stage's own bounded HAL I/O.
  virtual void run(CycleFrame& frame) noexcept = 0;
};

class StageRunner {
 public:
  explicit StageRunner(core::Clock& clock) noexcept : clock_(clock) {}

  // Setup path. Stages run in the order added; false when `phase` is already taken or out of
  // order (a phase before one already added): the list is DESIGN.md's order, not the caller's.
  bool add(CyclePhase phase, CycleStage& stage) noexcept;

  // RT path: every stage in order, each timed into stats.phase_ns[phase]; the stages' laps
  // into stats.substage_ns.
  void run(CycleFrame& frame, AppStats& stats) noexcept;

  std::size_t stage_count() const noexcept { return count_; }
  bool has(CyclePhase phase) const noexcept;
  // What each stage took in the last run() (ns; 0 for a phase not run). The cycle benchmark
  // reads it, so its per-stage figures are the same clock reads as the report's split.
  std::int64_t last_ns(CyclePhase phase) const noexcept {
    return last_ns_[static_cast<std::size_t>(phase)];
  }
  // The sub-stages of the stages added (bit k = Substage k): recorded every cycle.
  std::uint32_t substage_mask() const noexcept { return substage_mask_; }

 private:
  struct Entry {
    CyclePhase phase = CyclePhase::hal_read;
    CycleStage* stage = nullptr;
  };
  core::Clock& clock_;
  std::array<Entry, kCyclePhaseCount> stages_{};
  std::array<std::int64_t, kCyclePhaseCount> last_ns_{};
  std::size_t count_ = 0;
  std::uint32_t substage_mask_ = 0;
};

// The stage whose code a sub-stage times.
CyclePhase phase_of(Substage substage) noexcept;

}  // namespace trainer::app
