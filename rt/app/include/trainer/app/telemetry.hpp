// What the haptic cycle publishes to non-RT threads each cycle (through a core::TripleBuffer):
// a trivially copyable snapshot, read by the telemetry thread for display, the graphics host
// and recordings.
#pragma once

#include <array>
#include <cstdint>

namespace trainer::app {

constexpr std::size_t kMaxInstruments = 4;

struct InstrumentTelemetry {
  std::array<float, 5> joints{};         // pitch rad, yaw rad, insertion m, roll rad, grip rad
  std::array<float, 3> tip_m{};          // world frame
  std::array<float, 3> force_n{};        // commanded force on the tool after the safety chain
  std::array<float, 5> joint_efforts{};  // commanded, joint side (N·m, N)
  bool in_contact = false;
};

struct TelemetrySnapshot {
  std::uint64_t cycle = 0;
  std::int64_t time_ns = 0;
  std::uint32_t latched_faults = 0;
  std::uint32_t instrument_count = 0;
  std::array<InstrumentTelemetry, kMaxInstruments> instruments{};
};

}  // namespace trainer::app
