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
  for (std::size_t k = 0; k < kSubstageCount; ++k) {
    if (phase_of(static_cast<Substage>(k)) == phase) substage_mask_ |= 1U << k;
  }
  return true;
}

bool StageRunner::has(CyclePhase phase) const noexcept {
  for (std::size_t k = 0; k < count_; ++k) {
    if (stages_[k].phase == phase) return true;
  }
  return false;
}

void StageRunner::run(CycleFrame& frame, AppStats& stats) noexcept {
  stats.laps.begin_cycle();
  std::int64_t start_ns = clock_.now_ns();
  for (std::size_t k = 0; k < count_; ++k) {
    stats.laps.start_stage(clock_, start_ns);
    stages_[k].stage->run(frame);
    const std::int64_t end_ns = clock_.now_ns();
    const auto phase = static_cast<std::size_t>(stages_[k].phase);
    stats.phase_ns[phase].record(end_ns - start_ns);
    last_ns_[phase] = end_ns - start_ns;
    start_ns = end_ns;
  }
  stats.laps.end_cycle(stats.substage_ns, substage_mask_);
}

CyclePhase phase_of(Substage substage) noexcept {
  switch (substage) {
    case Substage::modal_near:
    case Substage::modal_collision:
    case Substage::modal_solve:
    case Substage::modal_step:
    case Substage::modal_reconstruct:
    case Substage::modal_refit: return CyclePhase::modal_models;
    case Substage::catheter_walls:
    case Substage::catheter_tools:
    case Substage::catheter_step:
    case Substage::catheter_reactions: return CyclePhase::catheters;
  }
  return CyclePhase::publish;  // not reached: every sub-stage is listed
}

}  // namespace trainer::app
