// Stage modal_models: the instruments against each reduced-modal model (the duct), its contact
// solve and step (Basdogan §VII; METHODS.md §1, §4), and its surface for the next collision.
// Owns: the modal models, their surfaces, tip and shaft/jaw contacts (SceneModels::modal).
// Reads: frame.instruments[i] pose, tip velocity, last tip; the catheters' particle positions
// (a particle near a model keeps its surface fresh); the catheters' wall reactions from their
// last step (ModalModelState::catheter_loads, applied and cleared here).
// Writes: frame.instruments[i] model_force_n, model_contact, model_indentation_m, the shaft's
// and jaws' wall forces (tool_forces), wall_segment_contact; per-model statistics.
#pragma once

#include <span>

#include "stages/modal_targets.hpp"
#include "trainer/app/app_stats.hpp"
#include "trainer/app/scene_models.hpp"
#include "trainer/app/stage_runner.hpp"

namespace trainer::app {

class ModalStage final : public CycleStage {
 public:
  ModalStage(std::span<ModalModelState> models, std::span<const CatheterModelState> catheters,
             AppStats& stats) noexcept
      : models_(models), catheters_(catheters), stats_(&stats) {}

  void run(CycleFrame& frame) noexcept override;

 private:
  // Applies and clears the catheters' pending wall reactions; returns their sum.
  Eigen::Vector3f apply_catheter_loads(ModalModelState& state) noexcept;
  // Is a touching tool or catheter particle near the model, or a contact holding? Only then is
  // its surface needed.
  bool anything_near(const ModalModelState& state,
                     std::span<const InstrumentFrame> instruments) const noexcept;
  // The contact solve with release of pulling contacts; the tools' reactions into the frame.
  // Returns the total force on the tissue from the tools.
  Eigen::Vector3f solve_contacts(ModalModelState& state, ModalTargets& targets,
                                 std::span<InstrumentFrame> instruments,
                                 bool& tool_touching) noexcept;
  // The tools' share of a solve that holds: tips at the tip, shafts and jaws at their points.
  Eigen::Vector3f apply_reactions(const ModalModelState& state, const ModalTargets& targets,
                                  std::span<const Eigen::Vector3f> on_tissue,
                                  std::span<InstrumentFrame> instruments,
                                  bool& tool_touching) noexcept;
  void refresh_surface(ModalModelState& state) noexcept;
  void run_model(std::size_t index, CycleFrame& frame) noexcept;

  std::span<ModalModelState> models_;
  std::span<const CatheterModelState> catheters_;
  AppStats* stats_;
};

}  // namespace trainer::app
