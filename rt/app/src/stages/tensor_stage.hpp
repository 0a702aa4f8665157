// Stage tensor_models: the instruments' tips against each Cotin tensor model (the liver;
// METHODS.md §3): the touched triangle's contact nodes follow the tip, TensorModel::solve
// (mutual influence, quasi-non-linear maps) gives the force, a pulling contact is released,
// and the deformed boundary is recomputed from the stored responses for the next collision.
// Far from every tool a tensor model costs nothing.
// Owns: the tensor models, their surfaces and tip contacts (SceneModels::tensor).
// Reads: frame.instruments[i] pose and last tip.
// Writes: frame.instruments[i] model_force_n, model_contact, model_indentation_m; per-model
// statistics.
#pragma once

#include <array>
#include <span>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/scene_models.hpp"
#include "trainer/app/stage_runner.hpp"

namespace trainer::app {

class TensorStage final : public CycleStage {
 public:
  TensorStage(std::span<TensorModelState> models, AppStats& stats) noexcept
      : models_(models), stats_(&stats) {}

  void run(CycleFrame& frame) noexcept override;

 private:
  struct Targets {
    std::array<model::TensorContact, model::TensorModel::kMaxContactsLimit> contacts{};
    std::array<std::size_t, model::TensorModel::kMaxContactsLimit> owner{};
    std::size_t count = 0;
    float indentation_m = 0.0F;  // the largest imposed displacement
  };
  // The tips' imposed node displacements. Two tools on one triangle's nodes cannot both impose
  // them: the later one lets go, as does one beyond the solver's capacity.
  void gather_targets(TensorModelState& state, std::span<InstrumentFrame> instruments,
                      Targets& out) noexcept;
  // Solve; a contact that would pull the tissue is released and the rest re-solved. The tools'
  // reactions into the frame.
  void solve_contacts(std::size_t index, Targets& targets,
                      std::span<InstrumentFrame> instruments) noexcept;
  static void refresh_surface(TensorModelState& state) noexcept;
  void run_model(std::size_t index, CycleFrame& frame) noexcept;

  std::span<TensorModelState> models_;
  AppStats* stats_;
};

}  // namespace trainer::app
