// Stage publish: what non-RT threads see of the cycle. New faults go to the log ring (once per
// latch), the cycle's snapshot to the telemetry triple buffer (the writer never waits).
// Owns: which faults were already logged.
// Reads: the supervisor's latched faults, frame.instrument_out, frame.newly_armed (a fault
// latched after arming is new, even of a kind logged before the reset).
// Writes: the log ring, the telemetry buffer, frame.faults_raised_at_publish.
#pragma once

#include <cstdint>

#include "trainer/app/stage_runner.hpp"
#include "trainer/app/telemetry.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/core/triple_buffer.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class PublishStage final : public CycleStage {
 public:
  PublishStage(const safety::SafetySupervisor& safety, core::LogRing& log,
               core::TripleBuffer<TelemetrySnapshot>& telemetry) noexcept
      : safety_(&safety), log_(&log), telemetry_(&telemetry) {}

  void run(CycleFrame& frame) noexcept override;

 private:
  const safety::SafetySupervisor* safety_;
  core::LogRing* log_;
  core::TripleBuffer<TelemetrySnapshot>* telemetry_;
  std::uint32_t last_logged_faults_ = 0;
};

}  // namespace trainer::app
