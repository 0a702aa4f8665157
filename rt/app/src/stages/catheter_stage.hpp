// Stage catheters: each particle catheter against the modal models' walls (point-based,
// ParticleSurfaceContact, found once per period with a margin) and the shafts and jaws of the
// instruments touching it (ray-based, ForcepsCatheterContact, grasping), as contact planes
// the chain evaluates at every substep; then its step (Basdogan §V-C-2; METHODS.md §2), the
// planes' mean forces back to the walls (next cycle) and to the tools, and the insertion goal.
// Owns: the catheters and their contacts (SceneModels::catheters).
// Reads: the modal models' surfaces (fresh where a particle or tool was near: the modal stage
// ran first), frame.instruments[i] pose, grip, tip velocity.
// Writes: the modal models' catheter_loads; frame.instruments[i] tool_forces,
// catheter_contact, grasping, squeeze_n; catheter and instrument statistics.
#pragma once

#include <span>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/scene_models.hpp"
#include "trainer/app/stage_runner.hpp"

namespace trainer::app {

class CatheterStage final : public CycleStage {
 public:
  // Catheter–wall contacts are found this far beyond touching, so a contact that closes during
  // the period is already a plane the substeps evaluate (more than a period's travel at 1 m/s).
  static constexpr float kWallDetectionMarginM = 0.001F;

  CatheterStage(std::span<CatheterModelState> catheters, std::span<ModalModelState> walls,
                float period_s, AppStats& stats) noexcept
      : catheters_(catheters), walls_(walls), period_s_(period_s), stats_(&stats) {}

  void run(CycleFrame& frame) noexcept override;

 private:
  // Each particle sphere against each modal model's deformed surface, as planes in the trainer
  // frame from `plane_count` on. False when a contact query failed.
  bool add_wall_planes(std::size_t index, std::size_t& plane_count) noexcept;
  bool add_tool_planes(CatheterModelState& state, std::span<const InstrumentFrame> instruments,
                       std::size_t& plane_count) noexcept;
  // Minus each wall plane's mean force, split over its triangle's vertices (model frame),
  // applied when the model steps next cycle.
  void return_wall_reactions(std::size_t index, std::size_t wall_plane_end) noexcept;
  bool return_tool_forces(CatheterModelState& state,
                          std::span<InstrumentFrame> instruments) noexcept;
  void track_insertion(std::size_t index) noexcept;
  void step_catheter(std::size_t index, CycleFrame& frame) noexcept;

  std::span<CatheterModelState> catheters_;
  std::span<ModalModelState> walls_;
  float period_s_;
  AppStats* stats_;
};

}  // namespace trainer::app
