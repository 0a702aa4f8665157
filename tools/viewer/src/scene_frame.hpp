// What the viewer draws for one telemetry frame, decoded from whatever source delivered it (the
// UDP stream now, a recording later): per scene model the state its surface is rebuilt from, the
// instruments' joints and contact forces, faults, and the timestamps of each hop. Non-RT: a
// normal program's data (vectors), filled by a FrameSource and consumed by the frame encoder.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "trainer/telemetry/wire_format.hpp"

namespace trainer::viewer {

// A force on one node of a modal model (model frame, N): what the static correction R·F needs.
struct NodeLoad {
  std::uint32_t node = 0;
  std::array<float, 3> force_n{};
};

// A displacement imposed on one contact node of a tensor model (model frame, m).
struct TensorContactState {
  std::uint32_t node = 0;
  std::array<float, 3> displacement_m{};
};

// One scene model's state, in scene order; only the members of its kind are used.
struct ModelState {
  std::vector<float> modal_coordinates;      // modal: q, first modes (kg^1/2·m)
  std::vector<NodeLoad> loads;               // modal: the forces of the step (static correction)
  std::vector<TensorContactState> contacts;  // tensor: imposed contact displacements
  std::vector<std::array<float, 3>> particles_m;  // catheter: particle positions, trainer frame
};

// An instrument's segments (trainer frame, m) and the force commanded on it (N).
struct InstrumentState {
  std::array<float, 3> shaft_start_m{};  // handle end of the shaft
  std::array<float, 3> hinge_m{};        // jaw hinge
  std::array<std::array<float, 3>, 2> jaw_tips_m{};
  std::array<float, 3> force_n{};  // commanded on the tool after the safety chain
  std::uint32_t flags = 0;         // telemetry::InstrumentFlag bits (contact, grasping, ...)
};

// A contact point and the force on the tissue there (trainer frame): a force arrow.
struct ContactArrow {
  std::uint32_t instrument = 0;
  std::array<float, 3> point_m{};
  std::array<float, 3> force_n{};
};

// Timestamps on CLOCK_REALTIME (ns since the epoch), 0 when the source does not know them.
struct FrameTimes {
  std::int64_t cycle_ns = 0;     // the appliance cycle the frame describes
  std::int64_t sent_ns = 0;      // the appliance's sender put it on the wire
  std::int64_t received_ns = 0;  // the viewer read it from its source
};

struct SceneFrame {
  std::uint64_t sequence = 0;  // the stream's sequence number
  std::uint64_t cycle = 0;
  FrameTimes times;
  std::uint32_t latched_faults = 0;
  std::vector<ModelState> models;            // one per scene model, scene order
  std::vector<InstrumentState> instruments;  // one per scene instrument, scene order
  std::vector<ContactArrow> contacts;
  // The session's trainee metrics so far, when the frame carries them (wire format 1.1).
  bool has_metrics = false;
  telemetry::SessionMetrics metrics{};
};

}  // namespace trainer::viewer
