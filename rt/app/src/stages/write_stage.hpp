// Stage hal_write: the cycle's outputs to the HAL. A faulted or unarmed controller still writes
// every cycle (zero effort, drives disabled), so the drives' own watchdogs see a live host
// holding them safe.
// Owns: the write-error streak.
// Reads: frame.commands (efforts from the forces stage), the supervisor's armed state.
// Writes: actuators and digital outputs (drive enable, fault lamp) through the HAL;
// frame.commands' enable flags (efforts zeroed unless armed); frame.instrument_out's forces
// zeroed unless armed; the supervisor's drive_fault / device_lost.
#pragma once

#include <cstdint>
#include <span>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/hal_binding.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/config/device.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class WriteStage final : public CycleStage {
 public:
  WriteStage(HalBinding hal, safety::SafetySupervisor& safety, const config::DigitalConfig& digital,
             AppStats& stats) noexcept
      : hal_(hal), safety_(&safety), digital_(digital), stats_(&stats) {}

  void run(CycleFrame& frame) noexcept override;

  // Zero effort on every channel, drives disabled, written at once (overrun fault, shutdown).
  void write_zero(std::span<hal::ActuatorCommand> commands) noexcept;
  // Every digital output low (shutdown).
  void write_digital_zero() noexcept {
    if (hal_.digital_outputs != nullptr) (void)hal_.digital_outputs->write_digital_outputs(0);
  }

 private:
  void write_outputs(std::span<hal::ActuatorCommand> commands, bool armed,
                     std::uint64_t cycle) noexcept;

  HalBinding hal_;
  safety::SafetySupervisor* safety_;
  config::DigitalConfig digital_;
  AppStats* stats_;
  std::uint32_t write_error_streak_ = 0;
};

}  // namespace trainer::app
