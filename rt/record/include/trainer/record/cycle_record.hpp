// One haptic cycle as the session recording keeps it (docs/recording.md): everything the cycle
// read from the HAL (return codes and data), the loop's timing and the reset request as the
// cycle consumed them, the overrun fault the loop raised after it, the cycle's outputs (actuator
// commands, digital outputs, the write return codes), the latched faults, a hash of the model
// state after the cycle, and a "derived" block of trainee-metric inputs (the metrics
// component's CycleSample fields) so metrics can be computed from a recording without a
// replay.
//
// Fixed size, trivially copyable, no implicit padding (explicit pad fields, always zero): the
// RT thread copies it into a core::SpscRing and the recording stores its bytes verbatim as one
// MCAP message (little-endian, the layout below, kCycleRecordLayout). A change to this struct
// changes kCycleRecordLayout; readers refuse other layouts.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>

namespace trainer::record {

inline constexpr std::uint32_t kCycleRecordLayout = 1;
inline constexpr std::size_t kMaxRecordInstruments = 4;
// Encoder and actuator channels a record holds: 4 instruments of 5 joints (checked when the
// recording is set up against the device's channel count).
inline constexpr std::size_t kMaxRecordChannels = kMaxRecordInstruments * 5;

struct RecordedEncoder {  // hal::EncoderSample
  std::int64_t counts;
  float position;
  std::uint8_t valid;
  std::uint8_t pad[3];
};

struct RecordedStatus {  // hal::ActuatorStatus
  float applied_effort;
  std::uint8_t enabled, saturated, fault, pad;
};

struct RecordedCommand {  // hal::ActuatorCommand
  float effort;
  std::uint8_t enable;
  std::uint8_t pad[3];
};

// The metrics component's InstrumentSample (rt/metrics cycle_sample.hpp, issue 18).
struct DerivedInstrument {
  std::array<float, 3> tip_m;            // trainer frame
  std::array<float, 3> tissue_force_n;   // models + catheters on the tool, before the safety chain
  std::array<float, 3> contact_point_m;  // where the largest of those forces acts
  float grip_rad;
  std::uint8_t tissue_contact, grasping;
  std::uint8_t pad[2];
};

// The metrics component's CycleSample less what the record has already (cycle = timing
// cycle_index, latched_faults).
struct DerivedSample {
  std::int64_t time_ns;  // the cycle's wake time
  std::uint32_t instrument_count;
  std::int32_t
      contact_model;  // scene model index (modal/tensor) with the largest total force, -1 none
  float insertion_depth_m;  // catheter tip past [model.insertion]'s entry; NaN without one
  std::uint32_t pad;
  std::array<DerivedInstrument, kMaxRecordInstruments> instruments;
};

struct CycleRecord {
  // Inputs: the loop's timing of the cycle (loop::CycleTiming).
  std::uint64_t cycle_index;
  std::int64_t deadline_ns;
  std::int64_t wake_ns;
  double dt_s;
  std::uint32_t overrun_streak;
  // Inputs: an explicit reset taken by this cycle's hal_read; HAL return codes
  // (hal::ReturnCode: 0 ok, 1 error, 2 deactivate; 255 = not called this cycle).
  std::uint8_t reset_requested;
  std::uint8_t encoder_rc;
  std::uint8_t status_rc;
  std::uint8_t digital_in_rc;
  std::uint32_t digital_in_levels;
  // The loop's overrun fault after this cycle's run (on_overrun_fault): the streak, 0 = none.
  std::uint32_t overrun_fault_streak;
  // Outputs: return codes of the first actuator / digital-output write of the cycle (the
  // hal_write stage's) and how many writes the cycle made (an overrun fault adds one).
  std::uint8_t actuator_write_rc;
  std::uint8_t digital_out_rc;
  std::uint8_t actuator_writes;
  std::uint8_t digital_out_writes;
  std::uint32_t digital_out_levels;
  std::uint32_t latched_faults;  // after the cycle (and its overrun fault)
  std::uint16_t channel_count;   // entries used in the arrays below
  std::uint16_t pad0;
  std::uint64_t state_hash;  // XXH3-64 of the model state after the cycle (docs/recording.md)
  std::array<RecordedEncoder, kMaxRecordChannels> encoders;  // input
  std::array<RecordedStatus, kMaxRecordChannels> status;     // input
  std::array<RecordedCommand, kMaxRecordChannels> commands;  // output (first write)
  DerivedSample derived;                                     // output
};

static_assert(std::is_trivially_copyable_v<CycleRecord>);
static_assert(sizeof(RecordedEncoder) == 16 && sizeof(RecordedStatus) == 8 &&
              sizeof(RecordedCommand) == 8 && sizeof(DerivedInstrument) == 44 &&
              sizeof(DerivedSample) == 24 + 4 * 44);
static_assert(sizeof(CycleRecord) == 72 + kMaxRecordChannels * (16 + 8 + 8) + 200,
              "no implicit padding: the bytes are the file format");
inline constexpr std::uint8_t kNotCalled = 255;

// The first output (or state hash) of `replayed` that differs from `recorded`, bit for bit, as
// "field: recorded X, replayed Y"; empty when all outputs are identical. Inputs (timing, HAL
// reads) are not compared: replay feeds them from the recording.
std::string first_output_difference(const CycleRecord& recorded, const CycleRecord& replayed);

}  // namespace trainer::record
