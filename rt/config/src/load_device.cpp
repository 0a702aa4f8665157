// The device file schema: [device], [digital], [[instrument]] with one sub-table per joint.
// Every key, unit, range and default here is documented in docs/config.md; keep them in step.
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "device_io_tables.hpp"
#include "table_reader.hpp"
#include "trainer/config/device.hpp"
#include "value_text.hpp"

namespace trainer::config {

std::string_view to_string(JointId joint) noexcept {
  switch (joint) {
    case JointId::pitch: return "pitch";
    case JointId::yaw: return "yaw";
    case JointId::insertion: return "insertion";
    case JointId::roll: return "roll";
    case JointId::grip: return "grip";
  }
  return "unknown";
}

std::string_view to_string(AbortConnectionOption option) noexcept {
  switch (option) {
    case AbortConnectionOption::fault_signal: return "fault_signal";
    case AbortConnectionOption::disable_voltage: return "disable_voltage";
    case AbortConnectionOption::quick_stop: return "quick_stop";
  }
  return "unknown";
}

hal::JointScale joint_scale(const JointConfig& joint) noexcept {
  hal::JointScale scale;
  scale.kind = joint.kind;
  scale.counts_per_rev = joint.counts_per_rev;
  scale.gear_ratio = joint.gear_ratio;
  scale.capstan_radius_m = joint.capstan_radius_m;
  scale.torque_constant_nm_per_a = joint.torque_constant_nm_per_a;
  scale.current_limit_a = joint.current_limit_a;
  scale.encoder_direction = joint.encoder_direction;
  scale.motor_direction = joint.motor_direction;
  return scale;
}

namespace {

using detail::ErrorSink;
using detail::kNanosecondsPerMicrosecond;
using detail::IntRange;
using detail::RealRange;
using detail::TableReader;

constexpr std::array<std::string_view, 3> kBackends = {"sim", "canopen", "usb"};
constexpr std::string_view kBackendNote =
    "GPIO lines combine with any of them through [device] digital_io = \"gpio\"";
constexpr std::size_t kCanopenBackend = 1;
constexpr std::size_t kUsbBackend = 2;

// [canopen] ranges (docs/config.md). Heartbeat times are u16 milliseconds in the drives'
// objects; the SYNC period a u32 of microseconds (0x1006) but a haptic loop needs <= 100 ms.
constexpr IntRange kNodeIdRange{1, 127};
constexpr IntRange kU32Range{0, 0xFFFF'FFFF};
constexpr IntRange kBitrateRange{0, 1'000'000};
constexpr std::int64_t kMinRealBitrate = 10'000;
constexpr IntRange kSyncPeriodRangeUs{0, 100'000};
constexpr std::int64_t kMinSyncPeriodUs = 100;
constexpr IntRange kHeartbeatRangeMs{1, 65'535};
constexpr IntRange kSdoTimeoutRangeMs{1, 10'000};
constexpr IntRange kBootTimeoutRangeMs{1, 60'000};
constexpr IntRange kDigitalNodeRange{-1, 127};
constexpr RealRange kRatedTorqueRangeNm = RealRange::left_open(0.0, 100.0);
constexpr std::int64_t kNanosecondsPerMillisecond = 1'000'000;
constexpr std::array<std::string_view, 3> kAbortOptions = {"fault_signal", "disable_voltage",
                                                          "quick_stop"};

constexpr IntRange kPlantSubstepRangeUs{1, 1000};
constexpr std::int64_t kDefaultPlantSubstepUs = 100;

constexpr IntRange kBitRange{-1, 31};
constexpr int kNotWired = -1;

constexpr RealRange kTrocarComponentRangeM = RealRange::closed(-10.0, 10.0);
constexpr RealRange kShaftLengthRangeM = RealRange::left_open(0.0, 1.0);
constexpr RealRange kJawLengthRangeM = RealRange::left_open(0.0, 0.1);
// Unit vectors are orthogonal when |cos angle| is below this (after normalising both).
constexpr double kOrthogonalityTolerance = 1e-6;

constexpr IntRange kCountsPerRevRange{1, std::int64_t{1} << 24};
constexpr RealRange kGearRatioRange = RealRange::left_open(0.0, 1000.0);
constexpr RealRange kCapstanRadiusRangeM = RealRange::left_open(0.0, 0.1);
constexpr RealRange kTorqueConstantRange = RealRange::left_open(0.0, 10.0);
constexpr RealRange kCurrentLimitRangeA = RealRange::left_open(0.0, 100.0);
constexpr RealRange kRevoluteLimitRangeRad = RealRange::closed(-20.0, 20.0);
constexpr RealRange kPrismaticLimitRangeM = RealRange::closed(-1.0, 1.0);
constexpr RealRange kInertiaRange = RealRange::left_open(0.0, 100.0);
constexpr RealRange kHandStiffnessRange = RealRange::closed(0.0, 1e6);
constexpr RealRange kHandDampingRange = RealRange::closed(0.0, 1e4);

// Simulated-plant defaults: a small laparoscopic handle and a relaxed hand.
constexpr double kDefaultInertiaKgM2 = 0.002;
constexpr double kDefaultMassKg = 0.15;
constexpr double kDefaultHandStiffnessNmPerRad = 5.0;
constexpr double kDefaultHandDampingNmsPerRad = 0.1;
constexpr double kDefaultHandStiffnessNPerM = 1500.0;
constexpr double kDefaultHandDampingNsPerM = 15.0;

// Key names and units differ between revolute and prismatic joints; the schema is the same.
struct JointKeys {
  std::string_view min_key;
  std::string_view max_key;
  std::string_view limit_unit;
  std::string_view inertia_key;
  std::string_view inertia_unit;
  double default_inertia;
  std::string_view stiffness_key;
  std::string_view stiffness_unit;
  double default_stiffness;
  std::string_view damping_key;
  std::string_view damping_unit;
  double default_damping;
  RealRange limit_range;
};

constexpr JointKeys kRevoluteKeys{
    .min_key = "min_rad",
    .max_key = "max_rad",
    .limit_unit = "radians",
    .inertia_key = "inertia_kg_m2",
    .inertia_unit = "kilogram square metres, reflected to the joint",
    .default_inertia = kDefaultInertiaKgM2,
    .stiffness_key = "hand_stiffness_nm_per_rad",
    .stiffness_unit = "newton-metres per radian",
    .default_stiffness = kDefaultHandStiffnessNmPerRad,
    .damping_key = "hand_damping_nms_per_rad",
    .damping_unit = "newton-metre-seconds per radian",
    .default_damping = kDefaultHandDampingNmsPerRad,
    .limit_range = kRevoluteLimitRangeRad,
};

constexpr JointKeys kPrismaticKeys{
    .min_key = "min_m",
    .max_key = "max_m",
    .limit_unit = "metres",
    .inertia_key = "mass_kg",
    .inertia_unit = "kilograms, reflected to the joint",
    .default_inertia = kDefaultMassKg,
    .stiffness_key = "hand_stiffness_n_per_m",
    .stiffness_unit = "newtons per metre",
    .default_stiffness = kDefaultHandStiffnessNPerM,
    .damping_key = "hand_damping_ns_per_m",
    .damping_unit = "newton-seconds per metre",
    .default_damping = kDefaultHandDampingNsPerM,
    .limit_range = kPrismaticLimitRangeM,
};

// Which key claimed each node id on the bus (empty = free), to refuse duplicates where the
// second one is written.
using NodeOwners = std::array<std::string, 128>;

CanopenJointConfig read_canopen_joint(TableReader& table, NodeOwners& owners,
                                      ErrorSink& errors) {
  CanopenJointConfig drive;
  drive.node_id =
      static_cast<std::uint8_t>(table.required_int("node_id", kNodeIdRange, "CANopen node id"));
  if (errors.ok()) {
    std::string& owner = owners[drive.node_id];
    if (!owner.empty()) {
      table.fail_value("node_id",
                       " is already used by " + owner + ": expected a node id unique on the bus");
    }
    owner = table.qualified("node_id");
  }
  drive.vendor_id = static_cast<std::uint32_t>(
      table.required_int("vendor_id", kU32Range, "identity object 0x1018 sub 1"));
  drive.product_code = static_cast<std::uint32_t>(
      table.required_int("product_code", kU32Range, "identity object 0x1018 sub 2"));
  if (table.has("revision")) {
    drive.revision = static_cast<std::uint32_t>(
        table.required_int("revision", kU32Range, "identity object 0x1018 sub 3"));
  }
  drive.motor_rated_torque_nm = table.required_double(
      "motor_rated_torque_nm", kRatedTorqueRangeNm, "newton-metres, the drive's object 0x6076");
  return drive;
}

// encoder_direction / motor_direction: 1 or -1 (default 1); 0 is refused like any value
// outside the set, with file:line, key, value and what was expected.
std::int8_t read_direction(TableReader& table, std::string_view key, std::string_view meaning) {
  const std::int64_t value = table.optional_int(key, 1, IntRange{-1, 1}, meaning);
  if (value == 0) {
    table.fail_value(key, ": expected 1 or -1 (" + std::string(meaning) + ")");
    return 1;
  }
  return static_cast<std::int8_t>(value);
}

JointConfig read_joint(TableReader& table, hal::JointKind kind, NodeOwners* owners,
                       ErrorSink& errors) {
  const bool prismatic = kind == hal::JointKind::prismatic;
  const JointKeys& keys = prismatic ? kPrismaticKeys : kRevoluteKeys;
  JointConfig joint;
  joint.kind = kind;
  joint.counts_per_rev = static_cast<std::int32_t>(
      table.required_int("counts_per_rev", kCountsPerRevRange,
                         "encoder counts per motor revolution, after quadrature"));
  joint.gear_ratio = table.required_double("gear_ratio", kGearRatioRange,
                                           "motor revolutions per joint revolution");
  if (prismatic) {
    joint.capstan_radius_m =
        table.required_double("capstan_radius_m", kCapstanRadiusRangeM, "metres");
  }
  joint.torque_constant_nm_per_a = table.required_double(
      "torque_constant_nm_per_a", kTorqueConstantRange, "newton-metres per ampere");
  joint.current_limit_a = table.required_double("current_limit_a", kCurrentLimitRangeA, "amperes");
  joint.min_position = table.required_double(keys.min_key, keys.limit_range, keys.limit_unit);
  joint.max_position = table.required_double(keys.max_key, keys.limit_range, keys.limit_unit);
  joint.inertia = table.optional_double(keys.inertia_key, keys.default_inertia, kInertiaRange,
                                        keys.inertia_unit);
  joint.hand_stiffness = table.optional_double(keys.stiffness_key, keys.default_stiffness,
                                               kHandStiffnessRange, keys.stiffness_unit);
  joint.hand_damping = table.optional_double(keys.damping_key, keys.default_damping,
                                             kHandDampingRange, keys.damping_unit);
  joint.encoder_direction = read_direction(table, "encoder_direction",
                                           "+1 as designed, -1 when the encoder counts down "
                                           "for a positive joint motion");
  joint.motor_direction = read_direction(table, "motor_direction",
                                         "+1 as designed, -1 when a positive motor torque "
                                         "turns the joint negative");
  if (owners != nullptr) joint.canopen = read_canopen_joint(table, *owners, errors);
  if (errors.ok() && joint.min_position >= joint.max_position) {
    table.fail_value(keys.max_key, " is not greater than " + std::string(keys.min_key) + " = " +
                                       detail::format_number(joint.min_position) + ": expected " +
                                       std::string(keys.min_key) + " < " +
                                       std::string(keys.max_key) + " (" +
                                       std::string(keys.limit_unit) + ")");
  }
  table.finish();
  return joint;
}

double dot(const Vec3& a, const Vec3& b) noexcept {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

std::string format_vec3(const Vec3& vector) {
  // Appended piece by piece: GCC 12 at -O3 raises a false -Wrestrict on "literal" + string.
  std::string text = "[";
  for (std::size_t i = 0; i < vector.size(); ++i) {
    if (i > 0) text += ", ";
    text += detail::format_number(vector[i]);
  }
  text += "]";
  return text;
}

// `owners` is null unless the backend is canopen (then every joint names its drive).
InstrumentDeviceConfig read_instrument(TableReader& table, NodeOwners* owners,
                                       ErrorSink& errors) {
  InstrumentDeviceConfig instrument;
  instrument.name = table.required_name("name");
  instrument.trocar_position_m =
      table.required_vec3("trocar_position_m", kTrocarComponentRangeM, "metres, trainer frame");
  instrument.shaft_axis = table.required_direction("shaft_axis");
  instrument.up_axis = table.required_direction("up_axis");
  if (errors.ok()) {
    const double cosine = dot(instrument.shaft_axis, instrument.up_axis);
    if (std::fabs(cosine) > kOrthogonalityTolerance) {
      table.fail_value(
          "up_axis",
          " is not orthogonal to shaft_axis " + format_vec3(instrument.shaft_axis) +
              " (cosine of the angle between them = " + detail::format_significant(cosine) +
              "): expected orthogonal within " + detail::format_number(kOrthogonalityTolerance));
    } else {
      // Remove the residual (at most 1e-6) so kinematics gets an exactly orthonormal pair.
      Vec3& up = instrument.up_axis;
      for (std::size_t i = 0; i < 3; ++i) up[i] -= cosine * instrument.shaft_axis[i];
      const double length = std::sqrt(dot(up, up));
      for (double& component : up) component /= length;
    }
  }
  instrument.shaft_length_m = table.required_double("shaft_length_m", kShaftLengthRangeM,
                                                    "metres, trocar-side end to jaw hinge");
  instrument.jaw_length_m =
      table.required_double("jaw_length_m", kJawLengthRangeM, "metres, jaw hinge to jaw tip");
  for (std::size_t i = 0; i < kJointCount; ++i) {
    const auto joint_id = static_cast<JointId>(i);
    const auto kind =
        joint_id == JointId::insertion ? hal::JointKind::prismatic : hal::JointKind::revolute;
    TableReader joint_table = table.required_table(to_string(joint_id));
    instrument.joints[i] = read_joint(joint_table, kind, owners, errors);
  }
  table.finish();
  return instrument;
}

DigitalConfig read_digital(TableReader& table, ErrorSink& errors) {
  constexpr std::string_view kInputUnit = "bit of the digital input word, -1 = not wired";
  constexpr std::string_view kOutputUnit = "bit of the digital output word, -1 = not wired";
  DigitalConfig digital;
  digital.estop_input_bit =
      static_cast<int>(table.required_int("estop_input_bit", kBitRange, kInputUnit));
  digital.enable_input_bit =
      static_cast<int>(table.required_int("enable_input_bit", kBitRange, kInputUnit));
  digital.drive_enable_output_bit =
      static_cast<int>(table.required_int("drive_enable_output_bit", kBitRange, kOutputUnit));
  digital.fault_lamp_output_bit =
      static_cast<int>(table.required_int("fault_lamp_output_bit", kBitRange, kOutputUnit));
  // Inputs and outputs are separate words (HAL read_digital_inputs / write_digital_outputs),
  // so a bit must be unique only within its own word.
  if (errors.ok() && digital.enable_input_bit != kNotWired &&
      digital.enable_input_bit == digital.estop_input_bit) {
    table.fail_value("enable_input_bit",
                     " is already used by " + table.qualified("estop_input_bit") +
                         ": expected distinct input bits (-1 = not wired may repeat)");
  }
  if (errors.ok() && digital.fault_lamp_output_bit != kNotWired &&
      digital.fault_lamp_output_bit == digital.drive_enable_output_bit) {
    table.fail_value("fault_lamp_output_bit",
                     " is already used by " + table.qualified("drive_enable_output_bit") +
                         ": expected distinct output bits (-1 = not wired may repeat)");
  }
  table.finish();
  return digital;
}

std::int64_t read_ms(TableReader& table, std::string_view key, std::int64_t fallback,
                     IntRange range, std::string_view meaning) {
  return table.optional_int(key, fallback, range, meaning) * kNanosecondsPerMillisecond;
}

CanopenConfig read_canopen(TableReader& table, ErrorSink& errors) {
  CanopenConfig bus;
  bus.interface = table.required_string("interface", "a SocketCAN interface name, e.g. can0");
  if (errors.ok() && (bus.interface.empty() || bus.interface.size() > 15)) {
    table.fail_value("interface", ": expected 1..15 characters (a Linux interface name)");
  }
  bus.bitrate = static_cast<std::uint32_t>(table.optional_int(
      "bitrate", 1'000'000, kBitrateRange, "bits per second, 0 = virtual bus"));
  if (errors.ok() && bus.bitrate != 0 && bus.bitrate < kMinRealBitrate) {
    table.fail_value("bitrate", ": expected 0 (a virtual bus, no load limit) or 10000 to "
                                "1000000 (bits per second, as set with ip link)");
  }
  bus.sync_period_ns =
      table.optional_int("sync_period_us", 0, kSyncPeriodRangeUs,
                         "microseconds, 0 = the loop period") *
      kNanosecondsPerMicrosecond;
  if (errors.ok() && bus.sync_period_ns != 0 &&
      bus.sync_period_ns < kMinSyncPeriodUs * kNanosecondsPerMicrosecond) {
    table.fail_value("sync_period_us", ": expected 0 (SYNC every loop period) or 100 to 100000 "
                                       "(microseconds, a whole multiple of the loop period)");
  }
  bus.master_node_id = static_cast<std::uint8_t>(
      table.optional_int("master_node_id", 127, kNodeIdRange, "node id of the master"));
  bus.master_heartbeat_ns =
      read_ms(table, "master_heartbeat_ms", 10, kHeartbeatRangeMs, "milliseconds");
  bus.drive_heartbeat_consumer_ns = read_ms(table, "drive_heartbeat_consumer_ms", 30,
                                            kHeartbeatRangeMs, "milliseconds, object 0x1016");
  bus.drive_heartbeat_ns =
      read_ms(table, "drive_heartbeat_ms", 10, kHeartbeatRangeMs, "milliseconds, object 0x1017");
  bus.drive_heartbeat_timeout_ns =
      read_ms(table, "drive_heartbeat_timeout_ms", 30, kHeartbeatRangeMs, "milliseconds");
  bus.rpdo_timeout_ns = read_ms(table, "rpdo_timeout_ms", 10, kHeartbeatRangeMs,
                                "milliseconds, RPDO1 event timer (deadline) on the drives");
  const auto option = table.required_choice("abort_connection", kAbortOptions);
  if (option) bus.abort_connection = static_cast<AbortConnectionOption>(*option + 1);
  bus.sdo_timeout_ns = read_ms(table, "sdo_timeout_ms", 100, kSdoTimeoutRangeMs, "milliseconds");
  bus.boot_timeout_ns =
      read_ms(table, "boot_timeout_ms", 3000, kBootTimeoutRangeMs, "milliseconds");
  bus.digital_inputs_node = static_cast<int>(table.optional_int(
      "digital_inputs_node", -1, kDigitalNodeRange, "node id, -1 = no digital inputs"));
  bus.digital_outputs_node = static_cast<int>(table.optional_int(
      "digital_outputs_node", -1, kDigitalNodeRange, "node id, -1 = no digital outputs"));
  for (std::string_view key : {"digital_inputs_node", "digital_outputs_node"}) {
    const int node = key == "digital_inputs_node" ? bus.digital_inputs_node
                                                  : bus.digital_outputs_node;
    if (errors.ok() && node == 0) table.fail_value(key, ": expected -1 or a node id 1..127");
  }
  // A drive must see at least two of the master's heartbeats inside its consumer time, and
  // the master two of each drive's, or one late frame trips the bus.
  if (errors.ok() && bus.drive_heartbeat_consumer_ns < 2 * bus.master_heartbeat_ns) {
    table.fail_value("drive_heartbeat_consumer_ms",
                     ": expected at least twice master_heartbeat_ms = " +
                         std::to_string(bus.master_heartbeat_ns / kNanosecondsPerMillisecond));
  }
  if (errors.ok() && bus.drive_heartbeat_timeout_ns < 2 * bus.drive_heartbeat_ns) {
    table.fail_value("drive_heartbeat_timeout_ms",
                     ": expected at least twice drive_heartbeat_ms = " +
                         std::to_string(bus.drive_heartbeat_ns / kNanosecondsPerMillisecond));
  }
  // With sync_period_us = 0 the loop period decides; the master checks it at configure.
  if (errors.ok() && bus.rpdo_timeout_ns < 2 * bus.sync_period_ns) {
    table.fail_value("rpdo_timeout_ms", ": expected at least two SYNC periods (sync_period_us = " +
                                            std::to_string(bus.sync_period_ns / 1000) + ")");
  }
  table.finish();
  return bus;
}

// [usb] ranges (docs/config.md). The watchdog range is the protocol's SET_WATCHDOG range; a
// serial number string descriptor holds at most 126 UTF-16 characters.
constexpr IntRange kUsbIdRange{0, 0xFFFF};
constexpr std::size_t kMaxUsbSerialChars = 126;
constexpr IntRange kUsbProtocolRange{1, 1};  // the versions this build speaks (hal/usbproto)
constexpr IntRange kUsbWatchdogRangeMs{2, 1000};
constexpr IntRange kUsbStaleLimitRange{1, 1000};
constexpr IntRange kUsbControlTimeoutRangeMs{1, 10'000};
constexpr IntRange kUsbStartTimeoutRangeMs{1, 60'000};
constexpr IntRange kUsbStopTimeoutRangeMs{1, 10'000};
constexpr IntRange kUsbEventPollRangeUs{50, 100'000};
constexpr std::size_t kUsbMaxChannels = 16;  // usbproto::kMaxChannels (config does not link hal)

UsbConfig read_usb(TableReader& table, ErrorSink& errors) {
  UsbConfig usb;
  usb.vendor_id = static_cast<std::uint16_t>(
      table.optional_int("vendor_id", 0x1209, kUsbIdRange, "USB vendor id (idVendor)"));
  usb.product_id = static_cast<std::uint16_t>(
      table.optional_int("product_id", 0x0001, kUsbIdRange, "USB product id (idProduct)"));
  usb.serial = table.required_string("serial", "the device's serial number string, \"\" = any");
  if (errors.ok() && usb.serial.size() > kMaxUsbSerialChars) {
    table.fail_value("serial", ": expected at most 126 characters (a USB string descriptor)");
  }
  usb.protocol_version = static_cast<std::uint8_t>(table.optional_int(
      "protocol_version", 1, kUsbProtocolRange, "the protocol version this build speaks"));
  if (table.has("min_firmware_version")) {
    usb.min_firmware_version = static_cast<std::uint16_t>(table.required_int(
        "min_firmware_version", kUsbIdRange, "major << 8 | minor, e.g. 0x0100 for 1.0"));
  }
  usb.watchdog_ms = static_cast<std::uint16_t>(table.optional_int(
      "watchdog_ms", 20, kUsbWatchdogRangeMs, "milliseconds, the device's watchdog"));
  usb.stale_limit_cycles = static_cast<std::uint32_t>(table.optional_int(
      "stale_limit_cycles", 2, kUsbStaleLimitRange, "loop cycles without a new IN report"));
  usb.control_timeout_ns = read_ms(table, "control_timeout_ms", 100, kUsbControlTimeoutRangeMs,
                                   "milliseconds");
  usb.start_timeout_ns =
      read_ms(table, "start_timeout_ms", 2000, kUsbStartTimeoutRangeMs, "milliseconds");
  usb.stop_timeout_ns =
      read_ms(table, "stop_timeout_ms", 100, kUsbStopTimeoutRangeMs, "milliseconds");
  usb.event_poll_ns = table.optional_int("event_poll_us", 10000, kUsbEventPollRangeUs,
                                         "microseconds") *
                      kNanosecondsPerMicrosecond;
  table.finish();
  return usb;
}

// The digital nodes must be drives of this file.
void check_digital_nodes(const CanopenConfig& bus, const NodeOwners& owners, TableReader& table,
                         ErrorSink& errors) {
  for (std::string_view key : {"digital_inputs_node", "digital_outputs_node"}) {
    const int node = key == "digital_inputs_node" ? bus.digital_inputs_node
                                                  : bus.digital_outputs_node;
    if (errors.ok() && node > 0 &&
        (owners[static_cast<std::size_t>(node)].empty() || node == bus.master_node_id)) {
      table.fail_value(key, ": expected -1 or the node_id of one of the joints' drives");
    }
  }
}

// [device] digital_io: the backend's own digital I/O or GPIO lines ([gpio], device_io_tables.cpp).
constexpr std::array<std::string_view, 2> kDigitalIoChoices = {"backend", "gpio"};

DeviceConfig read_device(const detail::ParsedFile& parsed, ErrorSink& errors) {
  DeviceConfig config;
  config.source_path = parsed.file.absolute_path;
  TableReader root = detail::root_reader(parsed, errors);

  TableReader device = root.required_table("device");
  config.name = device.required_name("name");
  const auto backend = device.required_choice("backend", kBackends, kBackendNote);
  if (backend) config.backend = std::string(kBackends[*backend]);
  const bool canopen = backend && *backend == kCanopenBackend;
  const bool usb = backend && *backend == kUsbBackend;
  config.plant_substep_ns = device.optional_int("plant_substep_us", kDefaultPlantSubstepUs,
                                                kPlantSubstepRangeUs, "microseconds") *
                            kNanosecondsPerMicrosecond;
  if (device.has("digital_io")) {
    const auto digital_io = device.required_choice("digital_io", kDigitalIoChoices);
    if (digital_io) config.digital_io = static_cast<DigitalIo>(*digital_io);
  }
  device.finish();

  TableReader digital = root.required_table("digital");
  config.digital = read_digital(digital, errors);

  // [gpio] belongs to digital_io = "gpio": otherwise root.finish() reports it as unknown.
  std::optional<TableReader> gpio_table;
  if (config.digital_io == DigitalIo::gpio) {
    gpio_table.emplace(root.required_table("gpio"));
    config.gpio = read_gpio(*gpio_table, config.digital, errors);
    check_gpio_wiring(config, digital, errors);
  }

  // [canopen] belongs to the canopen backend: for any other backend root.finish() reports it
  // as an unknown table.
  std::optional<TableReader> canopen_table;
  NodeOwners owners{};
  if (canopen) {
    canopen_table.emplace(root.required_table("canopen"));
    config.canopen = read_canopen(*canopen_table, errors);
    owners[config.canopen.master_node_id] = canopen_table->qualified("master_node_id");
  }

  // [usb] likewise belongs to the usb backend only.
  std::optional<TableReader> usb_table;
  if (usb) {
    usb_table.emplace(root.required_table("usb"));
    config.usb = read_usb(*usb_table, errors);
  }

  if (root.has("telemetry")) {
    TableReader telemetry = root.required_table("telemetry");
    config.telemetry = read_telemetry(telemetry);
  }

  auto instruments = root.array_of_tables("instrument", 1, kMaxDeviceInstruments, "instruments");
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    InstrumentDeviceConfig instrument =
        read_instrument(instruments[i], canopen ? &owners : nullptr, errors);
    for (std::size_t earlier = 0; errors.ok() && earlier < i; ++earlier) {
      if (config.instruments[earlier].name == instrument.name) {
        instruments[i].fail_value("name", " duplicates " + instruments[earlier].qualified("name") +
                                              ": expected unique instrument names");
      }
    }
    config.instruments.push_back(std::move(instrument));
  }
  if (canopen_table) check_digital_nodes(config.canopen, owners, *canopen_table, errors);
  if (canopen_table && config.digital_io == DigitalIo::gpio) {
    for (std::string_view key : {"digital_inputs_node", "digital_outputs_node"}) {
      const int node = key == "digital_inputs_node" ? config.canopen.digital_inputs_node
                                                    : config.canopen.digital_outputs_node;
      if (errors.ok() && node != -1) {
        canopen_table->fail_value(key, ": expected -1: the digital words come from GPIO lines "
                                       "(device.digital_io = \"gpio\")");
      }
    }
  }
  if (usb_table) {
    // One protocol channel per joint: at most kUsbMaxChannels / kJointCount instruments.
    constexpr std::size_t kUsbMaxInstruments = kUsbMaxChannels / kJointCount;
    if (errors.ok() && instruments.size() > kUsbMaxInstruments) {
      instruments[kUsbMaxInstruments].fail_value(
          "name", " is instrument " + std::to_string(kUsbMaxInstruments + 1) +
                      ": backend \"usb\" carries one channel per joint and at most " +
                      std::to_string(kUsbMaxChannels) + " channels: expected at most " +
                      std::to_string(kUsbMaxInstruments) + " instruments");
    }
  }
  root.finish();
  return config;
}

}  // namespace

namespace {

core::Expected<DeviceConfig> device_from_parsed(core::Expected<detail::ParsedFile> parsed) {
  if (!parsed) return std::move(parsed).error();
  ErrorSink errors;
  DeviceConfig config = read_device(*parsed, errors);
  if (!errors.ok()) return errors.error();
  return config;
}

}  // namespace

core::Expected<DeviceConfig> load_device(const std::filesystem::path& file) {
  return device_from_parsed(detail::parse_toml_file(file));
}

core::Expected<DeviceConfig> load_device_text(std::string_view text,
                                              const std::filesystem::path& file) {
  return device_from_parsed(detail::parse_toml_text(text, file));
}

}  // namespace trainer::config
