#include "stages/write_stage.hpp"

namespace trainer::app {

void WriteStage::write_zero(std::span<hal::ActuatorCommand> commands) noexcept {
  for (hal::ActuatorCommand& command : commands) command = hal::ActuatorCommand{};
  (void)hal_.actuators->write_actuators(commands);
}

void WriteStage::write_outputs(std::span<hal::ActuatorCommand> commands, bool armed,
                               std::uint64_t cycle) noexcept {
  for (hal::ActuatorCommand& command : commands) {
    if (!armed) command = hal::ActuatorCommand{};
    command.enable = armed;
  }
  const hal::ReturnCode written = hal_.actuators->write_actuators(commands);
  if (written == hal::ReturnCode::deactivate) {
    safety_->latch(safety::Fault::drive_fault, cycle);
  } else if (written != hal::ReturnCode::ok) {
    ++stats_->hal_write_errors;
    if (++write_error_streak_ > kToleratedHalErrorStreak)
      safety_->latch(safety::Fault::device_lost, cycle);
  } else {
    write_error_streak_ = 0;
  }
  if (hal_.digital_outputs != nullptr) {
    std::uint32_t levels = 0;
    if (armed && digital_.drive_enable_output_bit >= 0) {
      levels |= 1U << static_cast<unsigned>(digital_.drive_enable_output_bit);
    }
    if (!armed && digital_.fault_lamp_output_bit >= 0) {
      levels |= 1U << static_cast<unsigned>(digital_.fault_lamp_output_bit);
    }
    (void)hal_.digital_outputs->write_digital_outputs(levels);
  }
}

void WriteStage::run(CycleFrame& frame) noexcept {
  const bool armed = safety_->armed();
  if (armed) ++stats_->armed_cycles;
  write_outputs(frame.commands, armed, stats_->cycles);
  if (!armed) {
    // Nothing was commanded: an instrument rendered before another one's fault reports so.
    for (InstrumentTelemetry& out : frame.instrument_out) {
      out.force_n = {};
      out.joint_efforts = {};
    }
  }
}

}  // namespace trainer::app
