// The haptic app: the cycle's stages wired for one scene (shared/DESIGN.md "One cycle"):
//   hal_read → kinematics → modal_models → tensor_models → catheters → forces → hal_write → publish
// one file per stage in rt/app/src/stages/, each saying what it owns, reads and writes; the
// data between them is one CycleFrame (cycle_frame.hpp); the StageRunner runs and times them.
// A model stage runs only when the scene has a model of its kind.
//
// Everything the cycle touches is created at configure time from the arena; run_cycle() is
// noexcept, takes no locks and allocates nothing. It names only HAL interfaces, never a
// concrete backend.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/cycle_frame.hpp"
#include "trainer/app/hal_binding.hpp"
#include "trainer/app/rigid_transform.hpp"
#include "trainer/app/scene_models.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/app/telemetry.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/core/triple_buffer.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class HapticStages;  // the stage objects (rt/app/src/haptic_stages.hpp)
class HalTaps;       // the session recording's HAL taps (hal_taps.hpp)
class CycleTimeTrace;  // per-cycle compute times (compute_trace.hpp)

class HapticApp final : public loop::CycleTask {
  // The property test (tests/rt/app/haptic_app_property_test.cpp) puts the models in random
  // states through their own public calls; nothing else reaches inside.
  friend class HapticAppTestAccess;

 public:
  static constexpr std::size_t kMaxModels = kMaxSceneModels;
  static constexpr std::uint32_t kToleratedErrorStreak = kToleratedHalErrorStreak;

  // Setup path: checks the HAL offers the channels the scene needs, loads the scene's models
  // and carves all cycle state from `arena`. Errors name the scene/device item that does not
  // fit. `clock` is the loop's clock (log time stamps); the stages are timed on the real
  // monotonic clock whatever it is, so the split means the same in simulated time.
  static core::Expected<std::unique_ptr<HapticApp>> create(
      const config::SceneConfig& scene, HalBinding hal, core::Arena& arena, core::LogRing& log,
      core::TripleBuffer<TelemetrySnapshot>& telemetry, core::Clock& clock);

  core::Status run_cycle(const loop::CycleTiming& timing) noexcept override;
  void on_overrun_fault(std::uint32_t streak) noexcept override;

  // Setup path: record every cycle through `taps` (the HAL taps the app was created on, see
  // hal_taps.hpp): each cycle opens a record, the taps fill in what the HAL returned, the app
  // adds the reset taken, the latched faults, the state hash and the derived block.
  void set_recorder(HalTaps* taps) noexcept { recorder_ = taps; }
  // Setup path: write every cycle's stage and sub-stage times into `trace` (trainer --repeat;
  // sized before arming, nullptr: none).
  void set_compute_trace(CycleTimeTrace* trace) noexcept { compute_trace_ = trace; }
  // XXH3-64 of the state that determines future outputs (docs/recording.md "State hash"):
  // modal coordinates, velocities, accelerations and pending catheter loads; tensor
  // displacements and contact state; catheter particles and velocities; the instruments'
  // previous tips; the safety chain's latched faults and passivity energy. RT, no heap.
  std::uint64_t state_hash() const noexcept;

  // From any thread: ask the safety chain to arm at the next cycle (an explicit reset).
  void request_reset() noexcept;
  // RT or non-RT, after the loop stopped: zero every output, disable drives, latch shutdown.
  void shutdown() noexcept;

  const AppStats& stats() const noexcept { return stats_; }
  const safety::SafetySupervisor& safety() const noexcept { return safety_; }
  std::size_t instrument_count() const noexcept { return frame_.instruments.size(); }
  const std::vector<LoadedModelInfo>& models() const noexcept { return models_.info; }
  // The stages this scene runs, in order, and what each took in the last cycle (ns).
  std::vector<CyclePhase> stage_phases() const;
  std::int64_t last_stage_ns(CyclePhase phase) const noexcept { return runner_.last_ns(phase); }
  // Placement of the model named `name` (model frame → trainer frame), nullopt if the scene
  // has no such model. model_transform(index) is the same for models()[index].
  std::optional<RigidTransform> model_transform(const std::string& name) const;
  const RigidTransform& model_transform(std::size_t index) const noexcept {
    return models_.transforms[index];
  }
  // Non-RT, after the loop stopped: the current particle positions of the catheter model
  // named `name` (empty if the scene has no such catheter).
  std::vector<std::array<float, 3>> catheter_positions_m(const std::string& name) const;

  HapticApp(const HapticApp&) = delete;
  HapticApp& operator=(const HapticApp&) = delete;
  ~HapticApp();

 private:
  HapticApp(core::LogRing& log, core::Clock& clock, const safety::SafetyLimits& limits,
            std::size_t instrument_count) noexcept;
  core::Expected<void> carve_frame(const config::SceneConfig& scene, std::size_t channel_count,
                                   core::Arena& arena);

  core::LogRing& log_;
  core::Clock& clock_;
  core::MonotonicClock stage_clock_;
  safety::SafetySupervisor safety_;
  AppStats stats_{};
  SceneModels models_;
  CycleFrame frame_{};
  std::unique_ptr<HapticStages> stages_;
  StageRunner runner_{stage_clock_};
  HalTaps* recorder_ = nullptr;
  CycleTimeTrace* compute_trace_ = nullptr;
  // The models' force sums at the last recorded cycle (modal, then tensor, in scene order):
  // their increase is this cycle's force on each model (the record's contact_model).
  std::array<double, 2 * kMaxSceneModels> recorded_force_sums_{};

  void record_cycle() noexcept;
  std::int32_t largest_force_model() noexcept;
};

}  // namespace trainer::app
