#include "trainer/app/hal_taps.hpp"

#include <algorithm>
#include <string>
#include <thread>

namespace trainer::app {

core::Expected<std::unique_ptr<HalTaps>> HalTaps::create(HalBinding inner, RecordRing* ring) {
  if (inner.encoders == nullptr || inner.actuators == nullptr)
    return core::make_error("recording: the HAL offers no encoders or no actuators");
  const std::size_t channels =
      std::max(inner.encoders->encoder_count(), inner.actuators->actuator_count());
  if (channels > record::kMaxRecordChannels) {
    return core::make_error("recording: the device has " + std::to_string(channels) +
                            " encoder/actuator channels; a cycle record holds at most " +
                            std::to_string(record::kMaxRecordChannels));
  }
  return std::unique_ptr<HalTaps>(new HalTaps(inner, ring));
}

HalBinding HalTaps::binding() noexcept {
  return HalBinding{this, this, inner_.digital_inputs != nullptr ? this : nullptr,
                    inner_.digital_outputs != nullptr ? this : nullptr};
}

void HalTaps::push_open() noexcept {
  if (!open_) return;
  open_ = false;
  if (ring_ == nullptr) return;
  if (wait_when_full_) {
    while (ring_->full()) std::this_thread::yield();  // simulated time only (set_wait_when_full)
  }
  if (ring_->push(pending_)) ++pushed_;
}

void HalTaps::begin_cycle(const loop::CycleTiming& timing) noexcept {
  push_open();
  pending_ = record::CycleRecord{};
  pending_.cycle_index = timing.cycle_index;
  pending_.deadline_ns = timing.deadline_ns;
  pending_.wake_ns = timing.wake_ns;
  pending_.dt_s = timing.dt_s;
  pending_.overrun_streak = timing.overrun_streak;
  pending_.encoder_rc = record::kNotCalled;
  pending_.status_rc = record::kNotCalled;
  pending_.digital_in_rc = record::kNotCalled;
  pending_.actuator_write_rc = record::kNotCalled;
  pending_.digital_out_rc = record::kNotCalled;
  open_ = true;
}

void HalTaps::finish() noexcept {
  push_open();
}

hal::ReturnCode HalTaps::read_encoders(std::span<hal::EncoderSample> out) noexcept {
  const hal::ReturnCode rc = inner_.encoders->read_encoders(out);
  if (open_) {
    pending_.encoder_rc = static_cast<std::uint8_t>(rc);
    const std::size_t n = std::min(out.size(), record::kMaxRecordChannels);
    pending_.channel_count =
        static_cast<std::uint16_t>(std::max<std::size_t>(pending_.channel_count, n));
    for (std::size_t c = 0; c < n; ++c) {
      pending_.encoders[c].counts = out[c].counts;
      pending_.encoders[c].position = out[c].position;
      pending_.encoders[c].valid = out[c].valid ? 1 : 0;
    }
  }
  return rc;
}

hal::ReturnCode HalTaps::read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept {
  const hal::ReturnCode rc = inner_.actuators->read_actuator_status(out);
  if (open_) {
    pending_.status_rc = static_cast<std::uint8_t>(rc);
    const std::size_t n = std::min(out.size(), record::kMaxRecordChannels);
    pending_.channel_count =
        static_cast<std::uint16_t>(std::max<std::size_t>(pending_.channel_count, n));
    for (std::size_t c = 0; c < n; ++c) {
      pending_.status[c].applied_effort = out[c].applied_effort;
      pending_.status[c].enabled = out[c].enabled ? 1 : 0;
      pending_.status[c].saturated = out[c].saturated ? 1 : 0;
      pending_.status[c].fault = out[c].fault ? 1 : 0;
    }
  }
  return rc;
}

hal::ReturnCode HalTaps::write_actuators(std::span<const hal::ActuatorCommand> commands) noexcept {
  const hal::ReturnCode rc = inner_.actuators->write_actuators(commands);
  if (open_) {
    if (pending_.actuator_writes == 0) {
      pending_.actuator_write_rc = static_cast<std::uint8_t>(rc);
      const std::size_t n = std::min(commands.size(), record::kMaxRecordChannels);
      pending_.channel_count =
          static_cast<std::uint16_t>(std::max<std::size_t>(pending_.channel_count, n));
      for (std::size_t c = 0; c < n; ++c) {
        pending_.commands[c].effort = commands[c].effort;
        pending_.commands[c].enable = commands[c].enable ? 1 : 0;
      }
    }
    if (pending_.actuator_writes < 255) ++pending_.actuator_writes;
  }
  return rc;
}

hal::ReturnCode HalTaps::read_digital_inputs(std::uint32_t& levels) noexcept {
  const hal::ReturnCode rc = inner_.digital_inputs->read_digital_inputs(levels);
  if (open_) {
    pending_.digital_in_rc = static_cast<std::uint8_t>(rc);
    pending_.digital_in_levels = levels;
  }
  return rc;
}

hal::ReturnCode HalTaps::write_digital_outputs(std::uint32_t levels) noexcept {
  const hal::ReturnCode rc = inner_.digital_outputs->write_digital_outputs(levels);
  if (open_) {
    if (pending_.digital_out_writes == 0) {
      pending_.digital_out_rc = static_cast<std::uint8_t>(rc);
      pending_.digital_out_levels = levels;
    }
    if (pending_.digital_out_writes < 255) ++pending_.digital_out_writes;
  }
  return rc;
}

}  // namespace trainer::app
