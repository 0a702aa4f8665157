// SimDriveNode setup: parameter checks, the object dictionary and its reset defaults, the NMT
// resets, and the checks and effects of SDO writes (the dictionary's observer). The per-frame
// and per-SYNC behaviour is in sim_drive_node_cycle.cpp.
#include "trainer/hal_simdrive/sim_drive_node.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/objects.hpp"
#include "trainer/hal_canopen/pdo_dictionary.hpp"
#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::simdrive {

namespace co = trainer::hal::canopen;

namespace {

constexpr std::uint16_t kObjectDigitalInputs = 0x60FD;
constexpr std::uint16_t kObjectDigitalOutputs = 0x60FE;
constexpr std::uint8_t kSubCobId = 1;
constexpr std::uint8_t kSubTransmissionType = 2;
constexpr std::uint8_t kSubInhibitTime = 3;
constexpr std::uint8_t kSubEventTimer = 5;
constexpr std::int8_t kModeCst =
    static_cast<std::int8_t>(co::OperationMode::cyclic_synchronous_torque);

// Little-endian bytes of an SDO write as the entry's numeric value (sign-extended when signed).
std::int64_t written_value(const co::ObjectEntry& entry,
                           std::span<const std::uint8_t> value) noexcept {
  std::uint64_t raw = 0;
  const std::size_t size = std::min<std::size_t>(value.size(), 8);
  for (std::size_t i = 0; i < size; ++i) raw |= static_cast<std::uint64_t>(value[i]) << (8 * i);
  if (co::is_signed(entry.type()) && size > 0 && size < 8) {
    const std::uint64_t sign = std::uint64_t{1} << (8 * size - 1);
    if ((raw & sign) != 0) raw |= ~((sign << 1) - 1);
  }
  return static_cast<std::int64_t>(raw);
}

// CiA 301 v4.2 7.3.5 Table 69: identifiers no PDO may use.
bool restricted_can_id(std::uint32_t can_id) noexcept {
  return can_id == 0x000 || (can_id >= 0x001 && can_id <= 0x07F) ||
         (can_id >= 0x101 && can_id <= 0x180) || (can_id >= 0x581 && can_id <= 0x5FF) ||
         (can_id >= 0x601 && can_id <= 0x67F) || (can_id >= 0x6E0 && can_id <= 0x6FF) ||
         (can_id >= 0x701 && can_id <= 0x77F) || (can_id >= 0x780 && can_id <= 0x7FF);
}

bool accepted_transmission_type(std::int64_t type) noexcept {
  return (type >= 0 && type <= co::kTransmissionSynchronousMax) ||
         type == co::kTransmissionEventManufacturer || type == co::kTransmissionEventProfile;
}

}  // namespace

// ------------------------------------------------------------------------------ creation

SimDriveNode::SimDriveNode(const SimDriveNodeParams& params, EventLog& events)
    : params_(params), events_(events), nmt_(params.node_id), sdo_(od_, params.node_id) {}

core::Expected<std::unique_ptr<SimDriveNode>> SimDriveNode::create(const SimDriveNodeParams& params,
                                                                   EventLog& events) {
  const std::string who = "simulated drive node " + std::to_string(params.node_id) + ": ";
  if (!co::is_valid_node_id(params.node_id)) {
    return core::make_error("simulated drive: node id " + std::to_string(params.node_id) +
                            " outside 1..127");
  }
  if (params.software_version.size() > co::kMaxStringBytes) {
    return core::make_error(who + "software version '" + params.software_version +
                            "' longer than " + std::to_string(co::kMaxStringBytes) +
                            " characters (0x100A)");
  }
  if (params.device_name.size() > co::kMaxStringBytes) {
    return core::make_error(who + "device name '" + params.device_name + "' longer than " +
                            std::to_string(co::kMaxStringBytes) + " characters (0x1008)");
  }
  if (params.motor_rated_torque_mnm == 0) {
    return core::make_error(who + "motor rated torque (0x6076) is 0 mN·m: expected > 0");
  }
  const hal::JointScale& scale = params.scale;
  if (scale.counts_per_rev <= 0 || !(scale.gear_ratio > 0.0) || !std::isfinite(scale.gear_ratio) ||
      !(scale.torque_constant_nm_per_a > 0.0) || !std::isfinite(scale.torque_constant_nm_per_a) ||
      !(scale.current_limit_a >= 0.0) || !std::isfinite(scale.current_limit_a) ||
      (scale.kind == hal::JointKind::prismatic && !(scale.capstan_radius_m > 0.0))) {
    return core::make_error(
        who +
        "joint scale incomplete (counts per rev, gear ratio, torque constant, current "
        "limit, capstan radius for a prismatic joint must be positive)");
  }
  if (params.slow_down_ramp_ns < 0 || params.quick_stop_ramp_ns < 0 || params.sdo_timeout_ns <= 0) {
    return core::make_error(who + "ramps must be >= 0 and the SDO timeout > 0");
  }
  std::unique_ptr<SimDriveNode> node(new SimDriveNode(params, events));
  if (auto built = node->add_objects(); !built)
    return core::make_error(who + built.error().message);
  node->od_.set_observer(node.get());
  node->sdo_.set_timeout_ns(params.sdo_timeout_ns);
  const auto entries = node->od_.entries();
  for (std::size_t i = 0; i < entries.size(); ++i) node->defaults_[i] = entries[i].as_int();
  return node;
}

core::Expected<void> SimDriveNode::add_objects() {
  using co::Access;
  using co::DataType;
  const std::uint8_t n = params_.node_id;
  struct Def {
    std::uint16_t index;
    std::uint8_t sub;
    DataType type;
    Access access;
    bool mappable;
    std::int64_t value;
  };
  std::vector<Def> defs = {
      {co::kObjectDeviceType, 0, DataType::u32, Access::constant, false, kDeviceTypeServoDrive},
      {co::kObjectErrorRegister, 0, DataType::u8, Access::ro, true, 0},
      {co::kObjectConsumerHeartbeatTime, 0, DataType::u8, Access::constant, false,
       kConsumerHeartbeatEntries},
      {co::kObjectProducerHeartbeatTime, 0, DataType::u16, Access::rw, false, 0},
      {co::kObjectIdentity, 0, DataType::u8, Access::constant, false, 4},
      {co::kObjectIdentity, co::kIdentityVendorId, DataType::u32, Access::constant, false,
       params_.identity.vendor_id},
      {co::kObjectIdentity, co::kIdentityProductCode, DataType::u32, Access::constant, false,
       params_.identity.product_code},
      {co::kObjectIdentity, co::kIdentityRevision, DataType::u32, Access::constant, false,
       params_.identity.revision},
      {co::kObjectIdentity, co::kIdentitySerialNumber, DataType::u32, Access::constant, false,
       params_.identity.serial_number},
      {co::kObjectAbortConnectionOption, 0, DataType::i16, Access::rw, false, 1},
      {co::kObjectErrorCode, 0, DataType::u16, Access::ro, true, 0},
      {co::kObjectControlword, 0, DataType::u16, Access::rw, true, 0},
      {co::kObjectStatusword, 0, DataType::u16, Access::ro, true, 0},
      {co::kObjectQuickStopOption, 0, DataType::i16, Access::rw, false, 2},
      {co::kObjectShutdownOption, 0, DataType::i16, Access::rw, false, 0},
      {co::kObjectDisableOperationOption, 0, DataType::i16, Access::rw, false, 1},
      {co::kObjectFaultReactionOption, 0, DataType::i16, Access::rw, false, 2},
      {co::kObjectModesOfOperation, 0, DataType::i8, Access::rw, true, kModeCst},
      {co::kObjectModesOfOperationDisplay, 0, DataType::i8, Access::ro, true, kModeCst},
      {co::kObjectPositionActual, 0, DataType::i32, Access::ro, true, 0},
      {co::kObjectVelocityActual, 0, DataType::i32, Access::ro, true, 0},
      {co::kObjectTargetTorque, 0, DataType::i16, Access::rw, true, 0},
      {co::kObjectMaxTorque, 0, DataType::u16, Access::rw, true, params_.max_torque_permille},
      {co::kObjectMotorRatedTorque, 0, DataType::u32, Access::constant, false,
       params_.motor_rated_torque_mnm},
      {co::kObjectTorqueActual, 0, DataType::i16, Access::ro, true, 0},
      {co::kObjectSupportedDriveModes, 0, DataType::u32, Access::constant, false,
       co::supported_mode_bit(co::OperationMode::cyclic_synchronous_torque)},
      {kObjectDigitalInputs, 0, DataType::u32, Access::ro, true, 0},
      {kObjectDigitalOutputs, 0, DataType::u8, Access::constant, false, 2},
      {kObjectDigitalOutputs, 1, DataType::u32, Access::rw, true, 0},
      {kObjectDigitalOutputs, 2, DataType::u32, Access::rw, true,
       0xFFFF0000},  // manufacturer bits enabled
  };
  for (std::uint8_t sub = 1; sub <= kConsumerHeartbeatEntries; ++sub) {
    defs.push_back({co::kObjectConsumerHeartbeatTime, sub, DataType::u32, Access::rw, false, 0});
  }
  // PDOs: CiA 301 default COB-IDs; PDO 1 valid with CiA 402's predefined mapping, 2..4 not.
  constexpr std::array<std::uint16_t, kPdoCount> kRpdoBase = {co::kCobRpdo1Base, co::kCobRpdo2Base,
                                                              co::kCobRpdo3Base, co::kCobRpdo4Base};
  constexpr std::array<std::uint16_t, kPdoCount> kTpdoBase = {co::kCobTpdo1Base, co::kCobTpdo2Base,
                                                              co::kCobTpdo3Base, co::kCobTpdo4Base};
  for (std::size_t i = 0; i < kPdoCount; ++i) {
    const auto offset = static_cast<std::uint16_t>(i);
    const std::uint32_t invalid = i == 0 ? 0U : co::kPdoCobIdInvalid;
    const std::uint16_t rpdo_comm = co::kObjectRpdoCommunicationFirst + offset;
    const std::uint16_t tpdo_comm = co::kObjectTpdoCommunicationFirst + offset;
    const std::uint16_t rpdo_map = co::kObjectRpdoMappingFirst + offset;
    const std::uint16_t tpdo_map = co::kObjectTpdoMappingFirst + offset;
    defs.push_back({rpdo_comm, 0, DataType::u8, Access::constant, false, kSubEventTimer});
    defs.push_back(
        {rpdo_comm, kSubCobId, DataType::u32, Access::rw, false, invalid | (kRpdoBase[i] + n)});
    defs.push_back({rpdo_comm, kSubTransmissionType, DataType::u8, Access::rw, false,
                    co::kTransmissionEventProfile});
    defs.push_back({rpdo_comm, kSubEventTimer, DataType::u16, Access::rw, false, 0});
    defs.push_back({tpdo_comm, 0, DataType::u8, Access::constant, false, kSubEventTimer});
    defs.push_back({tpdo_comm, kSubCobId, DataType::u32, Access::rw, false,
                    invalid | co::kPdoCobIdNoRtr | (kTpdoBase[i] + n)});
    defs.push_back({tpdo_comm, kSubTransmissionType, DataType::u8, Access::rw, false,
                    co::kTransmissionEventProfile});
    defs.push_back({tpdo_comm, kSubInhibitTime, DataType::u16, Access::rw, false, 0});
    defs.push_back({tpdo_comm, kSubEventTimer, DataType::u16, Access::rw, false, 0});
    defs.push_back({rpdo_map, 0, DataType::u8, Access::rw, false, i == 0 ? 1 : 0});
    defs.push_back({tpdo_map, 0, DataType::u8, Access::rw, false, i == 0 ? 1 : 0});
    for (std::uint8_t sub = 1; sub <= co::PdoMapping::kMaxEntries; ++sub) {
      const bool first = i == 0 && sub == 1;
      defs.push_back({rpdo_map, sub, DataType::u32, Access::rw, false,
                      first ? co::encode_mapping_entry({co::kObjectControlword, 0, 16}) : 0});
      defs.push_back({tpdo_map, sub, DataType::u32, Access::rw, false,
                      first ? co::encode_mapping_entry({co::kObjectStatusword, 0, 16}) : 0});
    }
  }
  for (const Def& def : defs) {
    auto added = od_.add({.index = def.index,
                          .sub = def.sub,
                          .type = def.type,
                          .access = def.access,
                          .pdo_mappable = def.mappable,
                          .value = def.value,
                          .min = std::nullopt,
                          .max = std::nullopt});
    if (!added) return added;
  }
  if (auto added = od_.add_string(co::kObjectDeviceName, 0, co::Access::constant,
                                  params_.device_name);
      !added) {
    return added;
  }
  return od_.add_string(kObjectSoftwareVersion, 0, co::Access::constant, params_.software_version);
}

// ------------------------------------------------------------------------------ resets

void SimDriveNode::restore_defaults(bool application_too) noexcept {
  const auto entries = od_.entries();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const co::ObjectEntry& entry = entries[i];
    if (!co::is_numeric(entry.type())) continue;
    const bool communication = entry.index() >= 0x1000 && entry.index() <= 0x1FFF;
    if (communication || application_too)
      (void)od_.set_int(entry.index(), entry.sub(), defaults_[i]);
  }
}

void SimDriveNode::reset_pdo_runtime() noexcept {
  for (RpdoState& rpdo : rpdo_) {
    rpdo.latched = false;
    rpdo.deadline_armed = false;
    rpdo.length_error_reported = false;
  }
  for (TpdoState& tpdo : tpdo_) {
    tpdo.sync_counter = 0;
    tpdo.sent_once = false;
    tpdo.next_event_ns = now_.now_ns + static_cast<std::int64_t>(tpdo.event_timer_ms) * 1'000'000;
  }
}

void SimDriveNode::reload_all_pdos() noexcept {
  for (std::size_t i = 0; i < kPdoCount; ++i) {
    reload_pdo(co::PdoDirection::receive, i);
    reload_pdo(co::PdoDirection::transmit, i);
  }
}

void SimDriveNode::reload_pdo(co::PdoDirection direction, std::size_t index) noexcept {
  const auto number = static_cast<std::uint16_t>(index + 1);
  const std::uint16_t comm = co::pdo_communication_index(direction, number);
  const std::uint16_t map = co::pdo_mapping_index(direction, number);
  const auto cob =
      co::decode_pdo_cob_id(static_cast<std::uint32_t>(od_.get_int(comm, kSubCobId).value_or(0)));
  const auto type =
      static_cast<std::uint8_t>(od_.get_int(comm, kSubTransmissionType).value_or(255));
  const auto timer = static_cast<std::uint16_t>(od_.get_int(comm, kSubEventTimer).value_or(0));
  const auto count = static_cast<std::size_t>(od_.get_int(map, 0).value_or(0));
  std::array<std::uint32_t, co::PdoMapping::kMaxEntries> raw{};
  const std::size_t used = std::min(count, raw.size());
  for (std::size_t i = 0; i < used; ++i) {
    raw[i] =
        static_cast<std::uint32_t>(od_.get_int(map, static_cast<std::uint8_t>(i + 1)).value_or(0));
  }
  co::PdoMapping mapping;
  // Checked when written; a mapping that no longer fits (it cannot: the dictionary is fixed)
  // would leave the PDO empty.
  (void)co::map_from_dictionary({raw.data(), used}, direction, od_, mapping);
  if (direction == co::PdoDirection::receive) {
    RpdoState& rpdo = rpdo_[index];
    rpdo.valid = cob.valid && !cob.extended;
    rpdo.can_id = cob.can_id;
    rpdo.transmission_type = type;
    rpdo.event_timer_ms = timer;
    rpdo.mapping = mapping;
    rpdo.latched = false;
    rpdo.deadline_armed = false;
    rpdo.length_error_reported = false;
  } else {
    TpdoState& tpdo = tpdo_[index];
    tpdo.valid = cob.valid && !cob.extended;
    tpdo.can_id = cob.can_id;
    tpdo.transmission_type = type;
    tpdo.inhibit_100us = static_cast<std::uint16_t>(od_.get_int(comm, kSubInhibitTime).value_or(0));
    tpdo.event_timer_ms = timer;
    tpdo.mapping = mapping;
    tpdo.sync_counter = 0;
    tpdo.sent_once = false;
    tpdo.next_event_ns = now_.now_ns + static_cast<std::int64_t>(timer) * 1'000'000;
  }
}

void SimDriveNode::reload_heartbeat_consumer() noexcept {
  consumer_.clear();
  for (std::uint8_t sub = 1; sub <= kConsumerHeartbeatEntries; ++sub) {
    const auto entry =
        static_cast<std::uint32_t>(od_.get_int(co::kObjectConsumerHeartbeatTime, sub).value_or(0));
    (void)consumer_.add_entry(entry);  // duplicates are refused when written
  }
  heartbeat_lost_ = false;
}

void SimDriveNode::restart_heartbeat_producer() noexcept {
  heartbeat_period_ms_ =
      static_cast<std::uint16_t>(od_.get_int(co::kObjectProducerHeartbeatTime, 0).value_or(0));
  next_heartbeat_ns_ = now_.now_ns + static_cast<std::int64_t>(heartbeat_period_ms_) * 1'000'000;
}

co::Cia402Options SimDriveNode::options_from_dictionary() const noexcept {
  co::Cia402Options options;
  options.quick_stop_option =
      static_cast<std::int16_t>(od_.get_int(co::kObjectQuickStopOption, 0).value_or(2));
  options.shutdown_option =
      static_cast<std::int16_t>(od_.get_int(co::kObjectShutdownOption, 0).value_or(0));
  options.disable_operation_option =
      static_cast<std::int16_t>(od_.get_int(co::kObjectDisableOperationOption, 0).value_or(1));
  options.fault_reaction_option =
      static_cast<std::int16_t>(od_.get_int(co::kObjectFaultReactionOption, 0).value_or(2));
  options.abort_connection_option =
      static_cast<std::int16_t>(od_.get_int(co::kObjectAbortConnectionOption, 0).value_or(1));
  options.slow_down_ramp_ns = params_.slow_down_ramp_ns;
  options.quick_stop_ramp_ns = params_.quick_stop_ramp_ns;
  return options;
}

void SimDriveNode::boot() noexcept {
  sdo_.reset();
  reload_all_pdos();
  reload_heartbeat_consumer();
  restart_heartbeat_producer();
  rpdo_timed_out_ = false;
  sync_length_reported_ = false;
  const co::NmtState before = nmt_.state();
  queue(nmt_.boot(), TxKind::boot_up);
  ++counters_.boots;
  log(EventKind::boot);
  log(EventKind::nmt_state, static_cast<std::uint32_t>(before),
      static_cast<std::uint32_t>(nmt_.state()));
  publish_status();
}

void SimDriveNode::power_on(std::int64_t now_ns, std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  reset_application("power-on");
}

void SimDriveNode::reboot(std::int64_t now_ns, std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  reset_application("reboot");
}

void SimDriveNode::reset_application(const char* cause) noexcept {
  const co::PowerState before = power_.state();
  const bool was_on = power_.drive_function_enabled();
  restore_defaults(true);
  (void)power_.set_options(options_from_dictionary());
  power_.reset();
  (void)nmt_.apply(co::NmtCommand::reset_node);
  // Transition 1 (self-test passed) right away, so the master finds Switch on disabled.
  power_.update(0, now_.now_ns);
  after_power_change(before, was_on, cause);
  boot();
}

void SimDriveNode::reset_communication() noexcept {
  restore_defaults(false);
  boot();
}

// ------------------------------------------------------------------------------ SDO writes

bool SimDriveNode::pdo_valid(co::PdoDirection direction, std::size_t index) const noexcept {
  const std::uint16_t comm =
      co::pdo_communication_index(direction, static_cast<std::uint16_t>(index + 1));
  const auto value =
      static_cast<std::uint32_t>(od_.get_int(comm, kSubCobId).value_or(co::kPdoCobIdInvalid));
  return (value & co::kPdoCobIdInvalid) == 0;
}

std::uint32_t SimDriveNode::validate_pdo_communication(co::PdoDirection direction,
                                                       std::size_t index, std::uint8_t sub,
                                                       std::uint32_t value) const noexcept {
  const bool valid_now = pdo_valid(direction, index);
  if (sub == kSubCobId) {
    const co::PdoCobId requested = co::decode_pdo_cob_id(value);
    if (requested.extended) return co::kAbortInvalidValue;  // 29-bit ids are not supported
    if (!requested.valid) return 0;                         // disabling is always allowed
    if (restricted_can_id(requested.can_id)) return co::kAbortInvalidValue;
    const std::uint16_t comm =
        co::pdo_communication_index(direction, static_cast<std::uint16_t>(index + 1));
    const auto current =
        co::decode_pdo_cob_id(static_cast<std::uint32_t>(od_.get_int(comm, kSubCobId).value_or(0)));
    // CiA 301: the identifier of an existing PDO cannot change; invalidate it first.
    if (valid_now && requested.can_id != current.can_id) return co::kAbortInvalidValue;
    return 0;
  }
  if (sub == kSubTransmissionType)
    return accepted_transmission_type(value) ? 0 : co::kAbortInvalidValue;
  if (sub == kSubInhibitTime && valid_now) return co::kAbortInvalidValue;  // only while not valid
  return 0;
}

std::uint32_t SimDriveNode::validate_pdo_mapping(co::PdoDirection direction, std::size_t index,
                                                 std::uint8_t sub,
                                                 std::uint32_t value) const noexcept {
  if (pdo_valid(direction, index))
    return co::kAbortDeviceState;  // the PDO exists: invalidate it first
  const std::uint16_t map = co::pdo_mapping_index(direction, static_cast<std::uint16_t>(index + 1));
  std::array<std::uint32_t, co::PdoMapping::kMaxEntries> raw{};
  std::size_t count = 0;
  if (sub == 0) {
    if (value > co::PdoMapping::kMaxEntries) return co::kAbortPdoLength;
    count = value;
    for (std::size_t i = 0; i < count; ++i) {
      raw[i] = static_cast<std::uint32_t>(
          od_.get_int(map, static_cast<std::uint8_t>(i + 1)).value_or(0));
    }
  } else {
    if (od_.get_int(map, 0).value_or(0) != 0)
      return co::kAbortUnsupportedAccess;  // mapping enabled
    if (value == 0) return 0;              // clearing an entry
    raw[0] = value;
    count = 1;
  }
  co::PdoMapping mapping;
  std::uint32_t code = co::map_from_dictionary({raw.data(), count}, direction, od_, mapping);
  // WORKAROUND (protocol library): map_from_dictionary answers a read-only object in an RPDO
  // (or a write-only one in a TPDO) with the access aborts 0x06010002 / 0x06010001; CiA 301
  // 7.5.2.36 asks for "object cannot be mapped to the PDO", 0x06040041.
  if (code == co::kAbortWriteReadOnly || code == co::kAbortReadWriteOnly)
    code = co::kAbortNotMappable;
  return code;
}

std::uint32_t SimDriveNode::validate_write(const co::ObjectEntry& entry,
                                           std::span<const std::uint8_t> value) noexcept {
  const std::uint16_t index = entry.index();
  const std::uint8_t sub = entry.sub();
  const std::int64_t number = written_value(entry, value);
  const auto unsigned_value = static_cast<std::uint32_t>(number);
  if (index >= co::kObjectRpdoCommunicationFirst &&
      index < co::kObjectRpdoCommunicationFirst + kPdoCount) {
    return validate_pdo_communication(
        co::PdoDirection::receive, index - co::kObjectRpdoCommunicationFirst, sub, unsigned_value);
  }
  if (index >= co::kObjectTpdoCommunicationFirst &&
      index < co::kObjectTpdoCommunicationFirst + kPdoCount) {
    return validate_pdo_communication(
        co::PdoDirection::transmit, index - co::kObjectTpdoCommunicationFirst, sub, unsigned_value);
  }
  if (index >= co::kObjectRpdoMappingFirst && index < co::kObjectRpdoMappingFirst + kPdoCount) {
    return validate_pdo_mapping(co::PdoDirection::receive, index - co::kObjectRpdoMappingFirst, sub,
                                unsigned_value);
  }
  if (index >= co::kObjectTpdoMappingFirst && index < co::kObjectTpdoMappingFirst + kPdoCount) {
    return validate_pdo_mapping(co::PdoDirection::transmit, index - co::kObjectTpdoMappingFirst,
                                sub, unsigned_value);
  }
  if (index == co::kObjectConsumerHeartbeatTime) {
    if ((unsigned_value >> 24) != 0) return co::kAbortInvalidValue;
    const co::ConsumerEntry requested = co::decode_consumer_entry(unsigned_value);
    if (requested.node_id == 0 || requested.time_ms == 0) return 0;
    for (std::uint8_t other = 1; other <= kConsumerHeartbeatEntries; ++other) {
      if (other == sub) continue;
      const co::ConsumerEntry existing = co::decode_consumer_entry(static_cast<std::uint32_t>(
          od_.get_int(co::kObjectConsumerHeartbeatTime, other).value_or(0)));
      // CiA 301 7.5.2.22: one consumer time per producer node.
      if (existing.node_id == requested.node_id && existing.time_ms != 0)
        return co::kAbortParameterIncompatible;
    }
    return 0;
  }
  if (index == co::kObjectModesOfOperation) return number == kModeCst ? 0 : co::kAbortInvalidValue;
  if (index == co::kObjectAbortConnectionOption || index == co::kObjectQuickStopOption ||
      index == co::kObjectShutdownOption || index == co::kObjectDisableOperationOption ||
      index == co::kObjectFaultReactionOption) {
    co::Cia402Options options = options_from_dictionary();
    const auto option = static_cast<std::int16_t>(number);
    switch (index) {
      case co::kObjectAbortConnectionOption: options.abort_connection_option = option; break;
      case co::kObjectQuickStopOption: options.quick_stop_option = option; break;
      case co::kObjectShutdownOption: options.shutdown_option = option; break;
      case co::kObjectDisableOperationOption: options.disable_operation_option = option; break;
      default: options.fault_reaction_option = option; break;
    }
    return co::valid_options(options) ? 0 : co::kAbortInvalidValue;
  }
  return 0;
}

void SimDriveNode::on_written(const co::ObjectEntry& entry) noexcept {
  const std::uint16_t index = entry.index();
  if (index == co::kObjectControlword) {
    power_update(static_cast<std::uint16_t>(entry.as_int()), "controlword (SDO)");
  } else if (index == co::kObjectTargetTorque || index == co::kObjectMaxTorque ||
             index == co::kObjectModesOfOperation) {
    refresh_torque();
    publish_status();
  } else if (index == co::kObjectAbortConnectionOption || index == co::kObjectQuickStopOption ||
             index == co::kObjectShutdownOption || index == co::kObjectDisableOperationOption ||
             index == co::kObjectFaultReactionOption) {
    (void)power_.set_options(options_from_dictionary());
  } else if (index == co::kObjectConsumerHeartbeatTime) {
    reload_heartbeat_consumer();
    publish_status();
  } else if (index == co::kObjectProducerHeartbeatTime) {
    restart_heartbeat_producer();
  } else if (index >= co::kObjectRpdoCommunicationFirst &&
             index < co::kObjectRpdoCommunicationFirst + kPdoCount) {
    reload_pdo(co::PdoDirection::receive, index - co::kObjectRpdoCommunicationFirst);
  } else if (index >= co::kObjectTpdoCommunicationFirst &&
             index < co::kObjectTpdoCommunicationFirst + kPdoCount) {
    reload_pdo(co::PdoDirection::transmit, index - co::kObjectTpdoCommunicationFirst);
  } else if (index >= co::kObjectRpdoMappingFirst &&
             index < co::kObjectRpdoMappingFirst + kPdoCount) {
    reload_pdo(co::PdoDirection::receive, index - co::kObjectRpdoMappingFirst);
  } else if (index >= co::kObjectTpdoMappingFirst &&
             index < co::kObjectTpdoMappingFirst + kPdoCount) {
    reload_pdo(co::PdoDirection::transmit, index - co::kObjectTpdoMappingFirst);
  }
}

// ------------------------------------------------------------------------------ observation

bool SimDriveNode::take_output_changed() noexcept {
  const bool changed = output_changed_;
  output_changed_ = false;
  return changed;
}

std::uint32_t SimDriveNode::digital_outputs() const noexcept {
  const auto value = static_cast<std::uint32_t>(od_.get_int(kObjectDigitalOutputs, 1).value_or(0));
  const auto mask = static_cast<std::uint32_t>(od_.get_int(kObjectDigitalOutputs, 2).value_or(0));
  return value & mask;
}

const co::PdoMapping& SimDriveNode::rpdo_mapping(std::size_t pdo_number) const noexcept {
  return rpdo_[std::clamp<std::size_t>(pdo_number, 1, kPdoCount) - 1].mapping;
}

const co::PdoMapping& SimDriveNode::tpdo_mapping(std::size_t pdo_number) const noexcept {
  return tpdo_[std::clamp<std::size_t>(pdo_number, 1, kPdoCount) - 1].mapping;
}

}  // namespace trainer::hal::simdrive
