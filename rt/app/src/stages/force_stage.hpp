// Stage forces: what acts on each instrument to its joint efforts. Rigid objects add their
// penalty force at the tip; the soft-tissue models' tip force and the ray-based point forces
// on the shaft and jaws come from the model stages; command_instrument (force_command.hpp)
// runs the safety chain's force limits (finite check, clamp, slew, passivity) and the exact
// Jᵀ of every point force within the drives' effort limits.
// Owns: the scene's rigid objects, the instruments' contact memory (onsets).
// Reads: frame.instruments[i] (pose, tip velocity, joints, model and tool forces), the rigs.
// Writes: frame.commands (efforts), frame.instrument_out; the supervisor's force state;
// instrument statistics.
#pragma once

#include <span>

#include "stages/instrument_rig.hpp"
#include "trainer/app/app_stats.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/rigid_contact.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class ForceStage final : public CycleStage {
 public:
  static constexpr std::size_t kMaxObjects = 16;

  // Setup path: the scene's rigid objects (at most kMaxObjects) and the per-instrument memory.
  static core::Expected<ForceStage> create(const config::SceneConfig& scene,
                                           std::span<const InstrumentRig> rigs,
                                           safety::SafetySupervisor& safety, AppStats& stats,
                                           core::Arena& arena);

  void run(CycleFrame& frame) noexcept override;

 private:
  struct ObjectState {
    config::ObjectKind kind = config::ObjectKind::plane;
    model::RigidPlane plane;
    model::RigidSphere sphere;
    std::uint32_t touched_by_mask = 0;  // bit per instrument
  };
  ForceStage(std::span<const InstrumentRig> rigs, std::span<ObjectState> objects,
             std::span<bool> was_in_contact, safety::SafetySupervisor& safety,
             AppStats& stats) noexcept
      : rigs_(rigs),
        objects_(objects),
        was_in_contact_(was_in_contact),
        safety_(&safety),
        stats_(&stats) {}
  void render_instrument(std::size_t index, CycleFrame& frame) noexcept;

  std::span<const InstrumentRig> rigs_;
  std::span<ObjectState> objects_;
  std::span<bool> was_in_contact_;  // per instrument, last cycle
  safety::SafetySupervisor* safety_;
  AppStats* stats_;
};

}  // namespace trainer::app
