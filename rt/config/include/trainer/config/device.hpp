// Device configuration: what a device file (config/devices/*.toml) describes, as plain structs
// in SI units, and the loader that validates a file into them. A device file describes the
// mechanism (instruments on trocars, their joints, encoders, motors, digital lines) and which
// HAL backend drives it; it says nothing about the scene. Key-by-key reference: docs/config.md.
//
// Setup path only: the loader allocates and returns core::Expected; nothing here runs per cycle.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal/joint_scale.hpp"

namespace trainer::config {

using Vec3 = std::array<double, 3>;

// The joints of one instrument, in the order they appear in InstrumentDeviceConfig::joints.
enum class JointId : std::uint8_t { pitch, yaw, insertion, roll, grip };
inline constexpr std::size_t kJointCount = 5;
inline constexpr std::size_t kMaxDeviceInstruments = 4;

// Lower-case name of the joint, as used for the device file's sub-table ([instrument.pitch]).
std::string_view to_string(JointId joint) noexcept;
constexpr std::size_t index(JointId joint) noexcept {
  return static_cast<std::size_t>(joint);
}

// One axis of an instrument on its trocar. Positions are joint side: rad for revolute joints,
// m for the prismatic insertion joint; "effort" below is N·m or N accordingly.
struct JointConfig {
  hal::JointKind kind = hal::JointKind::revolute;  // insertion is prismatic, the rest revolute
  std::int32_t counts_per_rev = 0;        // encoder counts per MOTOR revolution (after quadrature)
  double gear_ratio = 0.0;                // motor revolutions per joint revolution
  double capstan_radius_m = 0.0;          // insertion only; 0 for revolute joints
  double torque_constant_nm_per_a = 0.0;  // motor torque per ampere
  double current_limit_a = 0.0;           // drive's continuous current limit
  double min_position = 0.0;              // joint limits, rad or m; min_position < max_position
  double max_position = 0.0;
  // Simulated plant (used by the sim backend, ignored by hardware backends).
  double inertia = 0.0;         // kg·m² (revolute) or kg (prismatic), reflected to the joint
  double hand_stiffness = 0.0;  // N·m/rad or N/m: the trainee's grip on the handle
  double hand_damping = 0.0;    // N·m·s/rad or N·s/m
};

// The encoder/motor conversion the HAL backends use for this joint.
hal::JointScale joint_scale(const JointConfig& joint) noexcept;

struct InstrumentDeviceConfig {
  std::string name;             // unique within the device file
  Vec3 trocar_position_m{};     // pivot point, in the trainer frame
  Vec3 shaft_axis{};            // unit vector, into the body at zero pitch/yaw (normalised on load)
  Vec3 up_axis{};               // unit vector orthogonal to shaft_axis; yaw turns about it
  double shaft_length_m = 0.0;  // trocar-side end of the shaft to the jaw hinge
  double jaw_length_m = 0.0;    // jaw hinge to jaw tip
  std::array<JointConfig, kJointCount> joints{};  // indexed by index(JointId)
};

// Which bit of the HAL's digital input / output word carries which signal; -1 = not wired.
// Inputs and outputs are separate words, so bits must be distinct only within each word.
struct DigitalConfig {
  int estop_input_bit = -1;
  int enable_input_bit = -1;
  int drive_enable_output_bit = -1;
  int fault_lamp_output_bit = -1;
};

struct DeviceConfig {
  std::filesystem::path source_path;  // absolute, lexically normal path of the file loaded
  std::string name;
  std::string backend;                // "sim" (the only backend implemented so far)
  std::int64_t plant_substep_ns = 0;  // sim backend: integration step of the simulated plant
  DigitalConfig digital;
  std::vector<InstrumentDeviceConfig> instruments;  // 1..kMaxDeviceInstruments, names unique
};

// Loads and validates a device file. On failure the message names the file, the line (when
// there is one), the key, the bad value and what was expected, e.g.
//   config/devices/sim.toml:31: instrument[0].pitch.gear_ratio = 0.0 is out of range: ...
core::Expected<DeviceConfig> load_device(const std::filesystem::path& file);

}  // namespace trainer::config
