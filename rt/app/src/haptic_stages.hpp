// The stage objects of one HapticApp (private to haptic_app.cpp): one member per stage of
// shared/DESIGN.md's cycle, the model stages only when the scene has such a model.
#pragma once

#include <optional>
#include <span>

#include "stages/catheter_stage.hpp"
#include "stages/force_stage.hpp"
#include "stages/instrument_rig.hpp"
#include "stages/kinematics_stage.hpp"
#include "stages/modal_stage.hpp"
#include "stages/publish_stage.hpp"
#include "stages/read_stage.hpp"
#include "stages/tensor_stage.hpp"
#include "stages/write_stage.hpp"

namespace trainer::app {

class HapticStages {
 public:
  std::span<InstrumentRig> rigs;
  std::optional<ReadStage> read;
  std::optional<KinematicsStage> kinematics;
  std::optional<ModalStage> modal;
  std::optional<TensorStage> tensor;
  std::optional<CatheterStage> catheters;
  std::optional<ForceStage> forces;
  std::optional<WriteStage> write;
  std::optional<PublishStage> publish;
};

}  // namespace trainer::app
