#include "stages/read_stage.hpp"

namespace trainer::app {
namespace {

bool bit_set(std::uint32_t levels, int bit) {
  return bit >= 0 && ((levels >> static_cast<unsigned>(bit)) & 1U) != 0;
}

}  // namespace

bool ReadStage::read_inputs(CycleFrame& frame) noexcept {
  const std::uint64_t cycle = frame.timing.cycle_index;
  safety::InputConditions& conditions = frame.conditions;
  const hal::ReturnCode read = hal_.encoders->read_encoders(frame.encoder_samples);
  const bool encoders_ok = read == hal::ReturnCode::ok;
  if (read == hal::ReturnCode::deactivate) safety_.latch(safety::Fault::device_lost, cycle);
  if (!encoders_ok) {
    ++stats_.hal_read_errors;
    if (++read_error_streak_ > kToleratedHalErrorStreak)
      safety_.latch(safety::Fault::device_lost, cycle);
  } else {
    read_error_streak_ = 0;
  }

  if (hal_.digital_inputs != nullptr) {
    std::uint32_t levels = 0;
    if (hal_.digital_inputs->read_digital_inputs(levels) == hal::ReturnCode::ok) {
      conditions.estop_active = bit_set(levels, digital_.estop_input_bit);
      conditions.enable_held =
          digital_.enable_input_bit < 0 || bit_set(levels, digital_.enable_input_bit);
    } else {
      // Unreadable safety inputs count as pressed e-stop: fail safe.
      conditions.estop_active = true;
      ++stats_.hal_read_errors;
    }
  }

  if (hal_.actuators->read_actuator_status(frame.actuator_status) != hal::ReturnCode::ok) {
    conditions.drive_fault = true;
  }
  for (const hal::ActuatorStatus& status : frame.actuator_status) {
    conditions.drive_fault = conditions.drive_fault || status.fault;
    if (status.saturated) ++stats_.saturated_actuator_cycles;
  }
  return encoders_ok;
}

void ReadStage::run(CycleFrame& frame) noexcept {
  const bool reset_requested = reset_requested_.exchange(false, std::memory_order_acq_rel);
  frame.reset_requested = reset_requested;
  frame.conditions = safety::InputConditions{};
  frame.encoders_ok = read_inputs(frame);
  // A reset clears only faults that have been reported: one raised since the last cycle
  // published its state (the overrun streak between cycles, a lost device found by this
  // cycle's reads) keeps the controller faulted, and the request is dropped as it is when an
  // input is active. Otherwise the reset would clear it before any telemetry or log saw it, and
  // arm on a device that failed this very cycle.
  if (reset_requested && safety_.raised_fault_total() == frame.faults_raised_at_publish) {
    safety_.request_reset();
  }
  const bool was_armed = safety_.armed();
  safety_.evaluate_inputs(frame.conditions, frame.timing.cycle_index);
  frame.newly_armed = !was_armed && safety_.armed();
  if (frame.newly_armed) {
    log_.write(frame.timing.wake_ns, core::LogLevel::info, "armed at cycle {}",
               frame.timing.cycle_index);
  }
}

}  // namespace trainer::app
