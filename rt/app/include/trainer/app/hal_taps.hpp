// HAL taps for the session recording (docs/recording.md): decorators around a HalBinding's
// interfaces that pass every call through unchanged and copy what it read or wrote into the
// current cycle's record::CycleRecord. The stages see the taps as their HAL and do not change.
// The haptic app opens a record when a cycle starts (begin_cycle) and fills the rest (reset,
// latched faults, state hash, derived block) after it; the record is pushed into the ring when
// the next cycle starts (an overrun fault raised after a cycle belongs to it) or at finish().
// A full ring drops the record and counts it, never waits.
//
// Replay uses the same taps around the replay HAL with no ring: pending() is then the
// replayed cycle's record, compared with the recorded one.
#pragma once

#include <cstdint>
#include <memory>
#include <span>

#include "trainer/app/hal_binding.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/spsc_ring.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/record/cycle_record.hpp"

namespace trainer::app {

// About 4 s at 1 kHz (0.4 s at 10 kHz) between two drains of the telemetry side (~30 Hz).
inline constexpr std::size_t kRecordRingCapacity = 4096;
using RecordRing = core::SpscRing<record::CycleRecord, kRecordRingCapacity>;

class HalTaps final : public hal::EncoderInterface,
                      public hal::ActuatorInterface,
                      public hal::DigitalInputInterface,
                      public hal::DigitalOutputInterface {
 public:
  // Setup path: the channel counts must fit a record. `ring` may be null (replay).
  static core::Expected<std::unique_ptr<HalTaps>> create(HalBinding inner, RecordRing* ring);

  // Setup path: where finished records go (null: nowhere).
  void set_ring(RecordRing* ring) noexcept { ring_ = ring; }
  // Setup path, simulated time only (no RT: offline runs and tests, where the cycle runs as
  // fast as the CPU allows and would outrun the writer): a full ring makes the cycle thread
  // yield until the writer has made room, so the recording is complete. In real time the taps
  // never wait: a full ring drops the record and counts it.
  void set_wait_when_full(bool wait) noexcept { wait_when_full_ = wait; }
  // The binding the haptic app runs on: the taps in place of each interface `inner` has.
  HalBinding binding() noexcept;

  // RT: pushes the previous cycle's record (if open) and opens this one.
  void begin_cycle(const loop::CycleTiming& timing) noexcept;
  // RT: pushes the open record; nothing is recorded afterwards (shutdown's writes).
  void finish() noexcept;
  record::CycleRecord& pending() noexcept { return pending_; }
  bool recording() const noexcept { return open_; }
  std::uint64_t pushed() const noexcept { return pushed_; }

  std::size_t encoder_count() const noexcept override { return inner_.encoders->encoder_count(); }
  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override;
  std::size_t actuator_count() const noexcept override {
    return inner_.actuators->actuator_count();
  }
  hal::ReturnCode write_actuators(std::span<const hal::ActuatorCommand> commands) noexcept override;
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept override;
  std::size_t digital_input_count() const noexcept override {
    return inner_.digital_inputs->digital_input_count();
  }
  hal::ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override;
  std::size_t digital_output_count() const noexcept override {
    return inner_.digital_outputs->digital_output_count();
  }
  hal::ReturnCode write_digital_outputs(std::uint32_t levels) noexcept override;

 private:
  HalTaps(HalBinding inner, RecordRing* ring) noexcept : inner_(inner), ring_(ring) {}
  void push_open() noexcept;

  HalBinding inner_;
  RecordRing* ring_;
  record::CycleRecord pending_{};
  bool open_ = false;
  bool wait_when_full_ = false;
  std::uint64_t pushed_ = 0;
};

}  // namespace trainer::app
