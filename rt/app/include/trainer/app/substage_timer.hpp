// Sub-stage timing inside the cycle's stages (issue 19): a lap timer with a fixed list of
// sub-stages, finer than the stage runner's phases. The stage runner marks each stage's start
// with the clock read it already makes; a stage calls lap(Substage::x) at the end of each piece
// of work, one clock read per lap, and the time since the previous mark goes to x. Laps of the
// same sub-stage in one cycle add up (several models, a surface refreshed twice). At the end of
// the cycle the runner records each sub-stage of the stages it runs into its histogram (0 when
// its code was skipped that cycle, so every sub-stage has one sample per cycle, as the stages
// do) and keeps the cycle's values (last_ns) for the per-cycle trace (trainer --repeat).
// A new sub-stage: an enumerator here (in cycle order), its name in kSubstageNames, its stage in
// phase_of() (stage_runner.cpp), a lap call where its work ends, a row in docs/report.md.
//
// RT path: noexcept, no heap, no branches on data but "has a clock". Outside a stage runner
// (a stage run directly by a test) no clock is set and lap() does nothing.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "trainer/core/clock.hpp"
#include "trainer/core/histogram.hpp"

namespace trainer::app {

// In cycle order. Each names the code between its lap and the previous mark (stage start or
// previous lap); the stage's time not covered by a lap (its bookkeeping after the last lap)
// is the stage's time minus the sum of its sub-stages.
enum class Substage : std::uint8_t {
  // modal_models, per modal model:
  modal_near = 0,     // the catheters' wall loads applied, "is a tool or particle near"
  modal_collision,    // tip and shaft/jaw targets gathered (grid queries, narrow phase)
  modal_solve,        // the imposed-displacement solve, releases, the tools' reactions
  modal_step,         // the duct's modal step (and its load statistics)
  modal_reconstruct,  // the deformed surface rebuilt from the modes (plus rest positions)
  modal_refit,        // the surface grid refit or rebuilt
  // catheters, per catheter:
  catheter_walls,      // particles against the modal walls (contact planes)
  catheter_tools,      // shafts and jaws against the catheter (planes, grasp)
  catheter_step,       // planes set, gravity, the explicit substeps
  catheter_reactions,  // plane forces back to the walls and tools, insertion depth
};
inline constexpr std::size_t kSubstageCount = 10;
inline constexpr std::array<const char*, kSubstageCount> kSubstageNames = {
    "modal_near",  "modal_collision", "modal_solve",    "modal_step",    "modal_reconstruct",
    "modal_refit", "catheter_walls",  "catheter_tools", "catheter_step", "catheter_reactions"};

class SubstageTimer {
 public:
  // Stage runner: a new cycle; clears the cycle's sums.
  void begin_cycle() noexcept {
    cycle_ns_.fill(0);
    touched_ = 0;
  }
  // Stage runner: a stage starts at `now_ns` on `clock` (the runner's own read).
  void start_stage(core::Clock& clock, std::int64_t now_ns) noexcept {
    clock_ = &clock;
    mark_ns_ = now_ns;
  }
  // A stage: the time since the previous mark goes to `substage`. One clock read.
  void lap(Substage substage) noexcept {
    if (clock_ == nullptr) return;
    const std::int64_t now_ns = clock_->now_ns();
    const auto index = static_cast<std::size_t>(substage);
    cycle_ns_[index] += now_ns - mark_ns_;
    touched_ |= 1U << index;
    mark_ns_ = now_ns;
  }
  // Stage runner: records the cycle's value of every sub-stage in `recorded` (bit k =
  // Substage k: the sub-stages of the stages it ran; 0 when the code was skipped this cycle)
  // and keeps the cycle's values.
  void end_cycle(std::array<core::LatencyHistogram, kSubstageCount>& substage_ns,
                 std::uint32_t recorded) noexcept {
    for (std::size_t k = 0; k < kSubstageCount; ++k) {
      last_ns_[k] = cycle_ns_[k];
      if ((recorded >> k) & 1U) substage_ns[k].record(cycle_ns_[k]);
    }
    clock_ = nullptr;
  }
  std::int64_t last_ns(Substage substage) const noexcept {
    return last_ns_[static_cast<std::size_t>(substage)];
  }
  // Sub-stages lapped in the last cycle (bit k = Substage k).
  std::uint32_t touched() const noexcept { return touched_; }

 private:
  core::Clock* clock_ = nullptr;
  std::int64_t mark_ns_ = 0;
  std::array<std::int64_t, kSubstageCount> cycle_ns_{};
  std::array<std::int64_t, kSubstageCount> last_ns_{};
  std::uint32_t touched_ = 0;
};

}  // namespace trainer::app
