// What the haptic cycle publishes to non-RT threads each cycle (through a core::TripleBuffer):
// a trivially copyable snapshot, read by the telemetry thread for display, the graphics host
// and recordings.
#pragma once

#include <array>
#include <cstdint>
#include <type_traits>

#include "trainer/telemetry/wire_format.hpp"

namespace trainer::app {

constexpr std::size_t kMaxInstruments = 4;

struct InstrumentTelemetry {
  std::array<float, 5> joints{};         // pitch rad, yaw rad, insertion m, roll rad, grip rad
  std::array<float, 3> tip_m{};          // world frame
  std::array<float, 3> force_n{};        // commanded force on the tool after the safety chain
  std::array<float, 5> joint_efforts{};  // commanded, joint side (N·m, N)
  bool in_contact = false;
  // Rigid scene objects (walls, spheres) at the tip: their force on the tool (forces stage).
  bool object_contact = false;
  std::array<float, 3> object_force_n{};
  // For drawing (publish stage, from the cycle's pose): trainer frame.
  std::array<float, 3> hinge_m{};
  std::array<float, 3> shaft_start_m{};
  std::array<float, 3> opening_direction{};
  std::uint8_t stream_flags = 0;  // telemetry::InstrumentFlag
};

struct TelemetrySnapshot {
  std::uint64_t cycle = 0;
  std::int64_t time_ns = 0;
  std::uint32_t latched_faults = 0;
  std::uint32_t instrument_count = 0;
  std::array<InstrumentTelemetry, kMaxInstruments> instruments{};
  // The scene's models for the telemetry stream (publish stage), in scene order; only the
  // used part of each array is written (counts first). Checked against the wire format's
  // capacities when the app is created.
  std::uint32_t model_count = 0;
  std::array<telemetry::ModelState, telemetry::kMaxModels> models{};
  // Contact points (trainer frame; force on the tissue), the largest kept beyond capacity.
  std::uint32_t contact_count = 0;
  bool contacts_truncated = false;
  std::array<telemetry::ContactPoint, telemetry::kMaxContacts> contacts{};
};
static_assert(std::is_trivially_copyable_v<TelemetrySnapshot>);

}  // namespace trainer::app
