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
#include <optional>
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

// The CiA 402 servo drive behind one joint (backend "canopen"): its node on the bus, the
// identity it must report (object 0x1018) and the motor rated torque that scales target and
// actual torque (0x6076, per-mille units in 0x6071/0x6072/0x6077).
struct CanopenJointConfig {
  std::uint8_t node_id = 0;          // 1..127, unique on the bus; 0 = not a CANopen joint
  std::uint32_t vendor_id = 0;       // 0x1018 sub 1
  std::uint32_t product_code = 0;    // 0x1018 sub 2
  std::optional<std::uint32_t> revision;  // 0x1018 sub 3, checked only when given
  double motor_rated_torque_nm = 0.0;     // 0x6076 (the drive reports mN·m)
};

// One axis of an instrument on its trocar. Positions are joint side: rad for revolute joints,
// m for the prismatic insertion joint; "effort" below is N·m or N accordingly.
struct JointConfig {
  hal::JointKind kind = hal::JointKind::revolute;  // insertion is prismatic, the rest revolute
  std::int32_t counts_per_rev = 0;        // encoder counts per MOTOR revolution (after quadrature)
  double gear_ratio = 0.0;                // motor revolutions per joint revolution
  double capstan_radius_m = 0.0;          // insertion only; 0 for revolute joints
  double torque_constant_nm_per_a = 0.0;  // motor torque per ampere
  double current_limit_a = 0.0;           // drive's continuous current limit
  // Wiring (hil check measures them): +1 as designed, -1 reversed. encoder_direction -1: the
  // encoder counts down when the joint moves positive; motor_direction -1: a positive motor
  // current turns the joint negative. Applied by hal::JointScale in every backend.
  std::int8_t encoder_direction = 1;
  std::int8_t motor_direction = 1;
  double min_position = 0.0;              // joint limits, rad or m; min_position < max_position
  double max_position = 0.0;
  // Simulated plant (used by the sim backend, ignored by hardware backends).
  double inertia = 0.0;         // kg·m² (revolute) or kg (prismatic), reflected to the joint
  double hand_stiffness = 0.0;  // N·m/rad or N/m: the trainee's grip on the handle
  double hand_damping = 0.0;    // N·m·s/rad or N·s/m
  CanopenJointConfig canopen;   // backend "canopen" only
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

// CiA 402 abort connection option code (0x6007): what a drive does by itself when it loses the
// master (heartbeat consumer timeout, RPDO deadline, bus-off).
enum class AbortConnectionOption : std::uint8_t {
  fault_signal = 1,     // go to Fault (fault reaction: torque removed)
  disable_voltage = 2,  // power stage off at once
  quick_stop = 3,       // quick stop (for a torque-mode drive: torque to zero, then off)
};
std::string_view to_string(AbortConnectionOption option) noexcept;

// The bus and the master's side of CANopen (backend "canopen"). Times are what goes into the
// drives' objects: heartbeats in whole milliseconds (0x1016/0x1017), SYNC in µs (0x1006).
struct CanopenConfig {
  std::string interface;                   // SocketCAN interface name, e.g. "can0", "vcan0"
  std::uint32_t bitrate = 1'000'000;       // bit/s of the bus (set with ip link): bus-load check
  std::int64_t sync_period_ns = 0;         // SYNC period, a whole multiple of the loop period;
                                           // 0 = every loop period
  std::uint8_t master_node_id = 0;         // node id of the master's heartbeat (0x700 + id)
  std::int64_t master_heartbeat_ns = 0;    // master's heartbeat producer time
  std::int64_t drive_heartbeat_consumer_ns = 0;  // 0x1016 on every drive: master lost after
  std::int64_t drive_heartbeat_ns = 0;     // 0x1017 on every drive
  std::int64_t drive_heartbeat_timeout_ns = 0;  // master's consumer time for each drive
  std::int64_t rpdo_timeout_ns = 0;        // RPDO1 event timer = deadline monitoring on drives
  AbortConnectionOption abort_connection = AbortConnectionOption::quick_stop;
  std::int64_t sdo_timeout_ns = 0;         // per SDO request at configure
  std::int64_t boot_timeout_ns = 0;        // wait for every node at configure
  int digital_inputs_node = -1;            // node whose 0x60FD bits 16..31 are the input word
  int digital_outputs_node = -1;           // node whose 0x60FE:01 bits 16..31 are the outputs
};

// Where the digital words ([digital] bits) come from: the backend's own I/O (the simulated
// bench's switches, a CANopen drive's digital inputs/outputs) or GPIO lines ([gpio], hal/gpiod).
enum class DigitalIo : std::uint8_t { backend, gpio };
enum class GpioBias : std::uint8_t { as_is, disable, pull_up, pull_down };
// Which level an input reports for a read after which it changed (docs/gpio.md).
enum class GpioLatch : std::uint8_t { active, inactive };

// One GPIO line ([[gpio.input]] / [[gpio.output]]): a bit of the HAL input or output word.
struct GpioLineConfig {
  std::string key;         // qualified, e.g. "gpio.input[0]", for messages
  int bit = -1;            // 0..31
  std::string chip;        // label, "gpiochipN" or a path
  std::string line_name;   // the line's name; empty when `offset` names it
  int offset = -1;         // the line's offset on the chip when line_name is empty
  bool active_low = false;
  GpioBias bias = GpioBias::as_is;
  GpioLatch latch = GpioLatch::active;  // inputs only
};

struct GpioConfig {
  std::string consumer;                 // the lines' user as gpioinfo shows it
  std::vector<GpioLineConfig> inputs;   // at most kMaxGpioLines in all
  std::vector<GpioLineConfig> outputs;
};
inline constexpr std::size_t kMaxGpioLines = 16;

// The USB haptic interface (backend "usb", docs/usb-host.md, protocol docs/usb-protocol.md): which
// device on the bus, what it must report, and the host's timing. One channel per joint in
// instrument order (instrument[0].pitch, .yaw, .insertion, .roll, .grip, instrument[1].pitch...).
struct UsbConfig {
  std::uint16_t vendor_id = 0x1209;        // pid.codes test VID
  std::uint16_t product_id = 0x0001;
  std::string serial;                      // serial number string; empty = any (the only one)
  std::uint8_t protocol_version = 1;       // the device's identity must report this
  std::optional<std::uint16_t> min_firmware_version;  // major << 8 | minor
  std::uint16_t watchdog_ms = 20;          // device watchdog, set at configure
  std::uint32_t stale_limit_cycles = 2;    // stale cycles in a row that latch device_stopped
  std::int64_t control_timeout_ns = 0;     // control requests and the OUT transfer
  std::int64_t start_timeout_ns = 0;       // activate: first acknowledged exchange
  std::int64_t stop_timeout_ns = 0;        // deactivate: zero + disable acknowledged
  std::int64_t event_poll_ns = 0;          // event thread's longest sleep without events
};

// The telemetry stream to the graphics host ([telemetry], docs/telemetry.md): where this
// installation's graphics host listens and how often to send. Absent table = off.
struct TelemetryConfig {
  bool enabled = false;
  std::string address;     // numeric IPv4 or IPv6 address (no name lookup on the appliance)
  std::uint16_t port = 0;  // UDP destination port
  std::uint32_t rate_hz = 60;  // frames per second, 30..120
  std::uint16_t source_port = 0;  // local UDP port the frames leave from; 0 = any (ephemeral)
};

struct DeviceConfig {
  std::filesystem::path source_path;  // absolute, lexically normal path of the file loaded
  std::string name;
  std::string backend;                // "sim", "canopen" or "usb"
  std::int64_t plant_substep_ns = 0;  // sim backend: integration step of the simulated plant
  DigitalConfig digital;
  std::vector<InstrumentDeviceConfig> instruments;  // 1..kMaxDeviceInstruments, names unique
  CanopenConfig canopen;              // [canopen], backend "canopen" only
  DigitalIo digital_io = DigitalIo::backend;  // [device] digital_io
  GpioConfig gpio;                    // [gpio], digital_io = "gpio" only
  UsbConfig usb;                      // [usb], backend "usb" only
  TelemetryConfig telemetry;          // [telemetry], optional
};

// Loads and validates a device file. On failure the message names the file, the line (when
// there is one), the key, the bad value and what was expected, e.g.
//   config/devices/sim.toml:31: instrument[0].pitch.gear_ratio = 0.0 is out of range: ...
core::Expected<DeviceConfig> load_device(const std::filesystem::path& file);
// The same for a device file's text already in memory, read as if it were `file` (named in
// messages; need not exist). load_device reads the file and parses it the same way.
core::Expected<DeviceConfig> load_device_text(std::string_view text,
                                              const std::filesystem::path& file);

}  // namespace trainer::config
