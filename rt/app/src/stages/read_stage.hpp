// Stage hal_read: the HAL's inputs and the safety chain's input checks.
// Owns: the read-error streak, the pending reset request.
// Reads: encoders, digital inputs (e-stop, enable), actuator status through the HAL.
// Writes: frame.encoder_samples, actuator_status, conditions, encoders_ok, newly_armed; the
// supervisor's input faults (device_lost, e-stop, drive fault, enable) and arming.
#pragma once

#include <atomic>
#include <cstdint>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/hal_binding.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/config/device.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class ReadStage final : public CycleStage {
 public:
  ReadStage(HalBinding hal, safety::SafetySupervisor& safety, const config::DigitalConfig& digital,
            AppStats& stats, core::LogRing& log) noexcept
      : hal_(hal), safety_(safety), digital_(digital), stats_(stats), log_(log) {}

  void run(CycleFrame& frame) noexcept override;

  // From any thread: arm at the next cycle (an explicit reset).
  void request_reset() noexcept { reset_requested_.store(true, std::memory_order_release); }

 private:
  bool read_inputs(CycleFrame& frame) noexcept;

  HalBinding hal_;
  safety::SafetySupervisor& safety_;
  config::DigitalConfig digital_;
  AppStats& stats_;
  core::LogRing& log_;
  std::uint32_t read_error_streak_ = 0;
  std::atomic<bool> reset_requested_{false};
};

}  // namespace trainer::app
