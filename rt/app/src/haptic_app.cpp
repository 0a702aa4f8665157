#include "trainer/app/haptic_app.hpp"

#include <string>

#include "haptic_stages.hpp"
#include "trainer/app/compute_trace.hpp"
#include "trainer/app/hal_taps.hpp"
#include "trainer/core/float_env.hpp"

namespace trainer::app {
namespace {

safety::SafetyLimits limits_from(const config::SafetyConfig& cfg) {
  safety::SafetyLimits limits;
  limits.max_force_n = static_cast<float>(cfg.max_force_n);
  limits.max_force_rate_n_per_s = static_cast<float>(cfg.max_force_rate_n_per_s);
  limits.max_joint_speed_rad_per_s = static_cast<float>(cfg.max_joint_speed_rad_per_s);
  limits.max_insertion_speed_m_per_s = static_cast<float>(cfg.max_insertion_speed_m_per_s);
  limits.passivity_energy_bound_j = static_cast<float>(cfg.passivity_energy_bound_j);
  limits.require_enable_input = cfg.require_enable_input;
  return limits;
}

// The scene's instruments and the HAL's channels, checked before anything is carved.
core::Expected<void> check_hal(const config::SceneConfig& scene, const HalBinding& hal) {
  const std::string where = scene.source_path.string();
  if (hal.encoders == nullptr || hal.actuators == nullptr) {
    return core::make_error(where + ": the selected HAL offers no encoders or no actuators");
  }
  const std::size_t instrument_count = scene.instruments.size();
  if (instrument_count == 0 || instrument_count > kMaxInstruments) {
    return core::make_error(where + ": a scene needs 1 to " + std::to_string(kMaxInstruments) +
                            " instruments, it has " + std::to_string(instrument_count));
  }
  const std::size_t channel_count = scene.device.instruments.size() * kinematics::kJointCount;
  if (hal.encoders->encoder_count() < channel_count ||
      hal.actuators->actuator_count() < channel_count) {
    return core::make_error(where + ": device '" + scene.device.name + "' offers " +
                            std::to_string(hal.encoders->encoder_count()) + " encoders and " +
                            std::to_string(hal.actuators->actuator_count()) +
                            " actuators; the scene needs " + std::to_string(channel_count));
  }
  return {};
}

}  // namespace

HapticApp::HapticApp(core::LogRing& log, core::Clock& clock, const safety::SafetyLimits& limits,
                     std::size_t instrument_count) noexcept
    : log_(log),
      clock_(clock),
      safety_(limits, instrument_count),
      stages_(std::make_unique<HapticStages>()) {}

HapticApp::~HapticApp() = default;

core::Expected<void> HapticApp::carve_frame(const config::SceneConfig& scene,
                                            std::size_t channel_count, core::Arena& arena) {
  auto instruments =
      arena.allocate_array<InstrumentFrame>(scene.instruments.size(), "instrument cycle frame");
  if (!instruments) return std::move(instruments).error();
  auto samples = arena.allocate_array<hal::EncoderSample>(channel_count, "encoder samples");
  if (!samples) return std::move(samples).error();
  auto commands = arena.allocate_array<hal::ActuatorCommand>(channel_count, "actuator commands");
  if (!commands) return std::move(commands).error();
  auto status = arena.allocate_array<hal::ActuatorStatus>(channel_count, "actuator status");
  if (!status) return std::move(status).error();
  auto out =
      arena.allocate_array<InstrumentTelemetry>(scene.instruments.size(), "instrument telemetry");
  if (!out) return std::move(out).error();
  frame_.instruments = *instruments;
  frame_.encoder_samples = *samples;
  frame_.commands = *commands;
  frame_.actuator_status = *status;
  frame_.instrument_out = *out;
  return {};
}

core::Expected<std::unique_ptr<HapticApp>> HapticApp::create(
    const config::SceneConfig& scene, HalBinding hal, core::Arena& arena, core::LogRing& log,
    core::TripleBuffer<TelemetrySnapshot>& telemetry, core::Clock& clock) {
  if (auto ok = check_hal(scene, hal); !ok) return std::move(ok).error();
  std::unique_ptr<HapticApp> app(
      new HapticApp(log, clock, limits_from(scene.safety), scene.instruments.size()));
  HapticStages& stages = *app->stages_;
  auto rigs = make_instrument_rigs(scene, arena);
  if (!rigs) return std::move(rigs).error();
  stages.rigs = *rigs;
  auto forces = ForceStage::create(scene, stages.rigs, app->safety_, app->stats_, arena);
  if (!forces) return std::move(forces).error();
  const std::size_t channel_count = scene.device.instruments.size() * kinematics::kJointCount;
  if (auto carved = app->carve_frame(scene, channel_count, arena); !carved)
    return std::move(carved).error();
  auto kinematics = KinematicsStage::create(stages.rigs, app->safety_, app->stats_, arena);
  if (!kinematics) return std::move(kinematics).error();
  if (auto loaded = load_scene_models(scene, arena, app->models_); !loaded)
    return std::move(loaded).error();

  SceneModels& models = app->models_;
  stages.read.emplace(hal, app->safety_, scene.device.digital, app->stats_, log);
  stages.kinematics.emplace(std::move(*kinematics));
  stages.forces.emplace(std::move(*forces));
  stages.write.emplace(hal, app->safety_, scene.device.digital, app->stats_);
  stages.publish.emplace(app->safety_, log, telemetry);
  if (auto published = stages.publish->publish_models(models, scene.source_path.string());
      !published) {
    return std::move(published).error();
  }
  StageRunner& runner = app->runner_;
  bool wired = runner.add(CyclePhase::hal_read, *stages.read) &&
               runner.add(CyclePhase::kinematics, *stages.kinematics);
  if (models.modal_count > 0) {
    stages.modal.emplace(models.modal_models(), models.catheter_models(), app->stats_);
    wired = wired && runner.add(CyclePhase::modal_models, *stages.modal);
  }
  if (models.tensor_count > 0) {
    stages.tensor.emplace(models.tensor_models(), app->stats_);
    wired = wired && runner.add(CyclePhase::tensor_models, *stages.tensor);
  }
  if (models.catheter_count > 0) {
    stages.catheters.emplace(models.catheter_models(), models.modal_models(),
                             models.catheter_period_s, app->stats_);
    wired = wired && runner.add(CyclePhase::catheters, *stages.catheters);
  }
  wired = wired && runner.add(CyclePhase::forces, *stages.forces) &&
          runner.add(CyclePhase::hal_write, *stages.write) &&
          runner.add(CyclePhase::publish, *stages.publish);
  if (!wired) return core::make_error("haptic app: the cycle's stages could not be wired in order");
  return app;
}

core::Status HapticApp::run_cycle(const loop::CycleTiming& timing) noexcept {
  const core::FlushDenormalsScope flush_denormals;  // core/float_env.hpp
  ++stats_.cycles;
  frame_.timing = timing;
  if (recorder_ != nullptr) recorder_->begin_cycle(timing);
  runner_.run(frame_, stats_);
  if (compute_trace_ != nullptr)
    compute_trace_->record_stages(timing.cycle_index, runner_, stats_.laps);
  if (recorder_ != nullptr) record_cycle();
  return frame_.encoders_ok ? core::Status::ok()
                            : core::Status{core::StatusCode::io_error, "encoder read failed"};
}

void HapticApp::request_reset() noexcept {
  stages_->read->request_reset();
}

void HapticApp::on_overrun_fault(std::uint32_t streak) noexcept {
  safety_.latch(safety::Fault::overrun_streak, stats_.cycles);
  stages_->write->write_zero(frame_.commands);
  if (recorder_ != nullptr && recorder_->recording()) {
    recorder_->pending().overrun_fault_streak = streak;
    recorder_->pending().latched_faults = safety_.latched_faults();
    recorder_->pending().state_hash = state_hash();
  }
  log_.write(clock_.now_ns(), core::LogLevel::error, "overrun streak of {} cycles: force zeroed",
             streak);
}

void HapticApp::shutdown() noexcept {
  safety_.latch(safety::Fault::shutdown, stats_.cycles);
  stages_->write->write_zero(frame_.commands);
  stages_->write->write_digital_zero();
}

std::vector<CyclePhase> HapticApp::stage_phases() const {
  std::vector<CyclePhase> phases;
  for (std::size_t k = 0; k < kCyclePhaseCount; ++k) {
    const auto phase = static_cast<CyclePhase>(k);
    if (runner_.has(phase)) phases.push_back(phase);
  }
  return phases;
}

std::optional<RigidTransform> HapticApp::model_transform(const std::string& name) const {
  for (std::size_t m = 0; m < models_.info.size(); ++m) {
    if (models_.info[m].name == name) return models_.transforms[m];
  }
  return std::nullopt;
}

std::vector<std::array<float, 3>> HapticApp::catheter_positions_m(const std::string& name) const {
  std::vector<std::array<float, 3>> positions;
  for (std::size_t c = 0; c < models_.catheter_count; ++c) {
    if (models_.catheters[c].name != name) continue;
    for (const Eigen::Vector3f& p : models_.catheters[c].catheter->positions_m()) {
      positions.push_back({p.x(), p.y(), p.z()});
    }
  }
  return positions;
}

}  // namespace trainer::app
