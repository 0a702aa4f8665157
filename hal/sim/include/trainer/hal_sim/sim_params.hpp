// Parameters of the simulated bench and its fixed channel layout. The app fills these plain
// structs from the device file (hal/sim never reads configuration itself); SimDevice::configure()
// validates them.
//
// Channel layout: N instruments (1..kMaxInstruments), each on a trocar pivot with five joints
// in the order below; channel index = instrument * kJointsPerInstrument + joint.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "trainer/hal/joint_scale.hpp"

namespace trainer::hal::sim {

inline constexpr std::size_t kJointsPerInstrument = 5;
inline constexpr std::size_t kMaxInstruments = 4;
inline constexpr std::size_t kMaxChannels = kJointsPerInstrument * kMaxInstruments;

// Joint index within an instrument (also the column order of a trajectory CSV).
inline constexpr std::size_t kPitchJoint = 0;      // rad, about the trocar pivot
inline constexpr std::size_t kYawJoint = 1;        // rad, about the trocar pivot
inline constexpr std::size_t kInsertionJoint = 2;  // m along the shaft (prismatic)
inline constexpr std::size_t kRollJoint = 3;       // rad about the shaft axis
inline constexpr std::size_t kGripJoint = 4;       // rad, jaw opening angle

inline constexpr std::array<const char*, kJointsPerInstrument> kJointNames = {
    "pitch", "yaw", "insertion", "roll", "grip"};

// Digital lines the simulated bench offers (bits 0 .. count-1 of the level words).
inline constexpr std::size_t kDigitalInputCount = 8;
inline constexpr std::size_t kDigitalOutputCount = 8;

// Accepted plant sub-step: 1 µs .. 1 ms. Below that the catch-up cost explodes; above it the
// integrator no longer resolves a 1 kHz command stream.
inline constexpr std::int64_t kMinPlantSubstepNs = 1'000;
inline constexpr std::int64_t kMaxPlantSubstepNs = 1'000'000;

// One joint of the simulated mechanism, joint-side SI. Revolute joints: kg·m², N·m/rad,
// N·m·s/rad, rad. Prismatic (insertion): kg, N/m, N·s/m, m. The trainee's hand is a
// spring-damper pulling the joint toward the scripted target; min/max are hard stops.
struct JointPlantParams {
  double inertia = 0.0;
  double hand_stiffness = 0.0;
  double hand_damping = 0.0;
  double min_position = 0.0;
  double max_position = 0.0;
};

struct SimInstrumentParams {
  std::string name;  // e.g. "left"; trajectory CSV rows refer to instruments by this name
  std::array<hal::JointScale, kJointsPerInstrument> scales{};  // insertion must be prismatic
  std::array<JointPlantParams, kJointsPerInstrument> plant{};
};

// Which digital input bit carries which switch; -1 = not wired (the bit always reads 0).
struct SimDigitalMap {
  int estop_input_bit = 0;   // 1 while the e-stop is pressed
  int enable_input_bit = 1;  // 1 while the enable (dead-man) switch is held
};

struct SimDeviceParams {
  std::string name;
  std::vector<SimInstrumentParams> instruments;
  std::int64_t plant_substep_ns = 50'000;
  SimDigitalMap digital;
  // "builtin:hold", "builtin:sweep", or a path to a trajectory CSV (see trainee_script.hpp).
  std::string script = "builtin:hold";
};

}  // namespace trainer::hal::sim
