#include "trainer/app/stage_runner.hpp"

#include <cstdint>

namespace trainer::app {

bool StageRunner::add(CyclePhase phase, CycleStage& stage) noexcept {
  if (count_ >= stages_.size()) return false;
  if (count_ > 0 &&
      static_cast<std::size_t>(stages_[count_ - 1].phase) >= static_cast<std::size_t>(phase)) {
    return false;
  }
  stages_[count_++] = Entry{phase, &stage};
  return true;
}

bool StageRunner::has(CyclePhase phase) const noexcept {
  for (std::size_t k = 0; k < count_; ++k) {
    if (stages_[k].phase == phase) return true;
  }
  return false;
}

void StageRunner::run(CycleFrame& frame,
                      std::array<core::LatencyHistogram, kCyclePhaseCount>& phase_ns) noexcept {
  std::int64_t start_ns = clock_.now_ns();
  for (std::size_t k = 0; k < count_; ++k) {
    stages_[k].stage->run(frame);
    const std::int64_t end_ns = clock_.now_ns();
    const auto phase = static_cast<std::size_t>(stages_[k].phase);
    phase_ns[phase].record(end_ns - start_ns);
    last_ns_[phase] = end_ns - start_ns;
    start_ns = end_ns;
  }
}

}  // namespace trainer::app
