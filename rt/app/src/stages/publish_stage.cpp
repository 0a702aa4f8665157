#include "stages/publish_stage.hpp"

namespace trainer::app {

void PublishStage::run(CycleFrame& frame) noexcept {
  const loop::CycleTiming& timing = frame.timing;
  if (frame.newly_armed) last_logged_faults_ = 0;
  const std::uint32_t faults = safety_->latched_faults();
  const std::uint32_t new_faults = faults & ~last_logged_faults_;
  if (new_faults != 0) {
    for (std::uint32_t bit = 1; bit != 0; bit <<= 1U) {
      if ((new_faults & bit) != 0 && bit != safety::bit(safety::Fault::not_armed)) {
        log_->write(timing.wake_ns, core::LogLevel::error, "fault latched: {} at cycle {}",
                    safety::to_string(static_cast<safety::Fault>(bit)), timing.cycle_index);
      }
    }
  }
  last_logged_faults_ = faults;
  frame.faults_raised_at_publish = safety_->raised_fault_total();

  TelemetrySnapshot& snapshot = telemetry_->write_slot();
  snapshot.cycle = timing.cycle_index;
  snapshot.time_ns = timing.wake_ns;
  snapshot.latched_faults = faults;
  snapshot.instrument_count = static_cast<std::uint32_t>(frame.instrument_out.size());
  for (std::size_t i = 0; i < frame.instrument_out.size(); ++i)
    snapshot.instruments[i] = frame.instrument_out[i];
  telemetry_->publish();
}

}  // namespace trainer::app
