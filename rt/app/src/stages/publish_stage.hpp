// Stage publish: what non-RT threads see of the cycle. New faults go to the log ring (once per
// latch), the cycle's snapshot to the telemetry triple buffer (the writer never waits).
// Owns: which faults were already logged; the map from each loaded model to its scene index.
// Reads: the supervisor's latched faults, frame.instrument_out, frame.instruments (pose and
// contacts), frame.newly_armed (a fault latched after arming is new, even of a kind logged
// before the reset), and — when given the scene's models — their published state: modal
// coordinates and last-step loads, tensor imposed contacts, catheter particles.
// Writes: the log ring, the telemetry buffer, frame.faults_raised_at_publish.
#pragma once

#include <array>
#include <cstdint>

#include "trainer/app/scene_models.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/app/telemetry.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/core/triple_buffer.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class PublishStage final : public CycleStage {
 public:
  PublishStage(const safety::SafetySupervisor& safety, core::LogRing& log,
               core::TripleBuffer<TelemetrySnapshot>& telemetry) noexcept
      : safety_(&safety), log_(&log), telemetry_(&telemetry) {}

  // Setup path: publish the scene's models too. Refuses a scene that does not fit the
  // telemetry wire format (more active modes, particles or contacts than it carries, a node
  // index above 65,535), naming the scene file and the model.
  core::Expected<void> publish_models(const SceneModels& models, const std::string& scene_file);

  void run(CycleFrame& frame) noexcept override;

 private:
  void publish_instruments(const CycleFrame& frame, TelemetrySnapshot& snapshot) const noexcept;
  void publish_model_state(TelemetrySnapshot& snapshot) const noexcept;

  const safety::SafetySupervisor* safety_;
  core::LogRing* log_;
  core::TripleBuffer<TelemetrySnapshot>* telemetry_;
  std::uint32_t last_logged_faults_ = 0;
  const SceneModels* models_ = nullptr;
  // Scene index (info order) of modal[k], tensor[k], catheters[k].
  std::array<std::uint8_t, kMaxSceneModels> modal_scene_index_{};
  std::array<std::uint8_t, kMaxSceneModels> tensor_scene_index_{};
  std::array<std::uint8_t, kMaxSceneModels> catheter_scene_index_{};
};

}  // namespace trainer::app
