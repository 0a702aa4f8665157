// What never changes about an instrument during a run: its trocar kinematics, its joints'
// kinds and first HAL channel, and its drives' effort limits. Built once from the scene and
// its device file; read by the kinematics and forces stages.
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"

namespace trainer::app {

struct InstrumentRig {
  kinematics::TrocarKinematics kinematics;
  std::array<hal::JointKind, kinematics::kJointCount> kinds{};  // for the encoder-jump limits
  // Per joint, the largest effort its drive accepts (N·m, N): the device's current limits.
  kinematics::JointVector effort_limits{};
  std::size_t first_channel = 0;  // HAL channel of the instrument's first joint
};

// One rig per scene instrument, carved from `arena`.
core::Expected<std::span<InstrumentRig>> make_instrument_rigs(const config::SceneConfig& scene,
                                                              core::Arena& arena);

}  // namespace trainer::app
