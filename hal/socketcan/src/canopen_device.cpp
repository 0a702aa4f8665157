#include "trainer/hal_socketcan/canopen_device.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "trainer/hal_socketcan/canopen_setup.hpp"
#include "trainer/hal_canopen/bus_error.hpp"
#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/objects.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_canopen/sync.hpp"

namespace trainer::hal::socketcan {

namespace co = trainer::hal::canopen;

const char* to_string(CanFault fault) noexcept {
  switch (fault) {
    case CanFault::none: return "none";
    case CanFault::bus_off: return "bus_off";
    case CanFault::emcy: return "emcy";
    case CanFault::drive_fault: return "drive_fault";
    case CanFault::heartbeat_lost: return "heartbeat_lost";
    case CanFault::node_rebooted: return "node_rebooted";
    case CanFault::node_not_operational: return "node_not_operational";
    case CanFault::pdo_timeout: return "pdo_timeout";
    case CanFault::bad_pdo: return "bad_pdo";
  }
  return "unknown";
}

namespace {

// CiA 402 digital inputs / physical outputs (not in the pure library's object list).
constexpr std::uint16_t kObjectDigitalInputs = 0x60FD;   // u32, bits 16..31 manufacturer
constexpr std::uint16_t kObjectDigitalOutputs = 0x60FE;  // sub 1: u32 physical outputs

// An RPDO of `mapping` to `node` carrying `values` (in mapping order). The values fit their
// fields by construction (u16 controlword, i16 torque clamped, u32 outputs).
can_frame rpdo_frame(const co::PdoMapping& mapping, std::uint8_t pdo_number, std::uint8_t node,
                     std::span<const std::int64_t> values) noexcept {
  can_frame frame{};
  frame.can_id = co::cob_id(co::FrameKind::rpdo, node, pdo_number);
  (void)mapping.pack(values, frame);
  return frame;
}

co::PdoMapping make_mapping(std::initializer_list<co::PdoField> fields) noexcept {
  co::PdoMapping mapping;
  for (const co::PdoField& field : fields) {
    (void)mapping.add(field.object.index, field.object.sub, field.object.bits, field.is_signed);
  }
  return mapping;
}

constexpr co::PdoField pdo_field(std::uint16_t index, std::uint8_t sub, std::uint8_t bits,
                                 bool is_signed) noexcept {
  return co::PdoField{{index, sub, bits}, is_signed, 0};
}

// Bits on the wire of a classic base-format data frame with `bytes` data bytes, with the
// worst-case bit stuffing of the stuffable part (CiA/ISO 11898: 34 + 8n bits stuffable) and
// the 3-bit interframe space.
double frame_bits(unsigned bytes) noexcept {
  const double stuffable = 34.0 + 8.0 * bytes;
  return stuffable + std::floor((stuffable - 1.0) / 4.0) + 13.0;
}

}  // namespace

CanopenDevice::CanopenDevice(core::Clock& clock, CanopenDeviceParams params,
                             std::optional<CanTransport> transport)
    : clock_(clock), params_(std::move(params)), transport_(std::move(transport)) {
  drive_of_node_.fill(-1);
}

CanopenDevice::~CanopenDevice() { deactivate(); }

const PdoLayout& pdo_layout() noexcept {
  static const PdoLayout layout = [] {
    PdoLayout l;
    l.rpdo1 = make_mapping({pdo_field(co::kObjectControlword, 0, 16, false),
                            pdo_field(co::kObjectTargetTorque, 0, 16, true)});
    l.rpdo2 = make_mapping({pdo_field(kObjectDigitalOutputs, 1, 32, false)});
    l.tpdo1 = make_mapping({pdo_field(co::kObjectStatusword, 0, 16, false),
                            pdo_field(co::kObjectPositionActual, 0, 32, true),
                            pdo_field(co::kObjectTorqueActual, 0, 16, true)});
    l.tpdo2 = make_mapping({pdo_field(co::kObjectVelocityActual, 0, 32, true),
                            pdo_field(kObjectDigitalInputs, 0, 32, false)});
    return l;
  }();
  return layout;
}

double CanopenDevice::estimate_bus_load(const CanopenDeviceParams& params) noexcept {
  if (params.bitrate == 0 || params.sync_period_ns <= 0) return 0.0;
  const double drives = static_cast<double>(params.drives.size());
  double bits_per_sync = frame_bits(0);               // SYNC
  bits_per_sync += drives * frame_bits(4);            // RPDO1
  bits_per_sync += drives * frame_bits(8);            // TPDO1
  // TPDO2 (velocity, digital inputs): every SYNC from the digital-inputs node, every
  // kDiagnosticPdoEverySyncs-th from the others.
  const double inputs_nodes = params.digital_inputs_node > 0 ? 1.0 : 0.0;
  bits_per_sync += inputs_nodes * frame_bits(8) +
                   (drives - inputs_nodes) * frame_bits(8) / kDiagnosticPdoEverySyncs;
  if (params.digital_outputs_node > 0) bits_per_sync += frame_bits(4);  // RPDO2
  const double sync_s = static_cast<double>(params.sync_period_ns) * 1e-9;
  double bits_per_s = bits_per_sync / sync_s;
  if (params.drive_heartbeat_ns > 0)
    bits_per_s += drives * frame_bits(1) / (static_cast<double>(params.drive_heartbeat_ns) * 1e-9);
  if (params.master_heartbeat_ns > 0)
    bits_per_s += frame_bits(1) / (static_cast<double>(params.master_heartbeat_ns) * 1e-9);
  return bits_per_s / static_cast<double>(params.bitrate);
}

std::string CanopenDevice::drive_label(std::size_t index) const {
  const DriveParams& drive = params_.drives[index];
  return "node " + std::to_string(drive.node_id) + " (" + drive.channel_name + ")";
}

core::Expected<void> CanopenDevice::check_params() const {
  const CanopenDeviceParams& p = params_;
  if (p.drives.empty() || p.drives.size() > kMaxDrives) {
    return core::make_error(p.name + ": " + std::to_string(p.drives.size()) +
                            " drives, expected 1.." + std::to_string(kMaxDrives));
  }
  if (p.loop_period_ns <= 0 || p.sync_period_ns < p.loop_period_ns ||
      p.sync_period_ns % p.loop_period_ns != 0) {
    return core::make_error(p.name + ": canopen.sync_period_us = " +
                            std::to_string(p.sync_period_ns / 1000) +
                            " is not a whole multiple of the loop period (" +
                            std::to_string(p.loop_period_ns / 1000) +
                            " us): expected the SYNC period to be 1, 2, 3 ... loop periods");
  }
  if (p.rpdo_timeout_ns < 2 * p.sync_period_ns) {
    return core::make_error(p.name + ": canopen.rpdo_timeout_ms = " +
                            std::to_string(p.rpdo_timeout_ns / 1'000'000) +
                            " is shorter than two SYNC periods (" +
                            std::to_string(p.sync_period_ns / 1000) +
                            " us each): the drives would time out between commands");
  }
  if (p.max_pdo_age_syncs < 1 || p.max_pdo_age_syncs > 1000) {
    return core::make_error(p.name + ": max_pdo_age_syncs = " +
                            std::to_string(p.max_pdo_age_syncs) + ", expected 1..1000");
  }
  std::array<bool, 128> used{};
  for (const DriveParams& drive : p.drives) {
    if (!co::is_valid_node_id(drive.node_id) || used[drive.node_id] ||
        drive.node_id == p.master_node_id) {
      return core::make_error(p.name + ": " + drive.channel_name + ": node id " +
                              std::to_string(drive.node_id) +
                              " is invalid or used twice: expected unique ids 1..127");
    }
    used[drive.node_id] = true;
    if (!(drive.motor_rated_torque_nm > 0.0) || !(drive.scale.max_effort() > 0.0)) {
      return core::make_error(p.name + ": " + drive.channel_name +
                              ": rated torque and current limit must be positive");
    }
  }
  const double load = estimate_bus_load(p);
  if (load > 1.0) {
    char text[64];
    std::snprintf(text, sizeof text, "%.0f%%", load * 100.0);
    return core::make_error(
        p.name + ": the cyclic traffic of " + std::to_string(p.drives.size()) +
        " drives every " + std::to_string(p.sync_period_ns / 1000) + " us needs " + text +
        " of the " + std::to_string(p.bitrate) +
        " bit/s bus (worst-case stuffing): expected at most 100%; lengthen "
        "canopen.sync_period_us (a multiple of the loop period), split the drives over two "
        "buses, or set canopen.bitrate = 0 for a virtual bus (vcan)");
  }
  return {};
}

void CanopenDevice::reset_rt_state() noexcept {
  for (Drive& drive : drives_) {
    drive.statusword = 0;
    drive.tpdo1_seen = false;
    drive.tpdo1_sync = 0;
    drive.tpdo2_seen = false;
    drive.tpdo2_sync = 0;
    drive.controlword = co::kCommandShutdown;
    drive.target_permille = 0;
    drive.saturated = false;
  }
  cycles_ = 0;
  syncs_sent_ = 0;
  rt_started_ = false;
  digital_outputs_ = 0;
  heartbeats_.clear();
  const auto timeout_ms =
      static_cast<std::uint16_t>(params_.drive_heartbeat_timeout_ns / 1'000'000);
  for (const Drive& drive : drives_) (void)heartbeats_.add(drive.node, timeout_ms);
  const CanCounters transport = diagnostics_.transport;
  const double load = diagnostics_.bus_load;
  diagnostics_ = CanDiagnostics{};
  diagnostics_.transport = transport;
  diagnostics_.bus_load = load;
}

void CanopenDevice::latch(CanFault fault, std::uint8_t node) noexcept {
  if (diagnostics_.faults == 0) {
    diagnostics_.first_fault = fault;
    diagnostics_.first_fault_node = node;
  }
  diagnostics_.faults |= static_cast<std::uint32_t>(fault);
}

// ------------------------------------------------------------------------------ RT cycle

void CanopenDevice::handle_frame(const can_frame& frame, std::int64_t now_ns) noexcept {
  const co::FrameClass kind = co::classify(frame);
  if (kind.kind == co::FrameKind::error_frame) {
    ++diagnostics_.error_frames;
    if (const auto error = co::decode_bus_error(frame)) {
      if (error->bus_off) latch(CanFault::bus_off, 0);
    }
    return;
  }
  if (!kind.ok()) {
    ++diagnostics_.frames_rejected;
    return;
  }
  const std::int16_t index =
      kind.node_id <= co::kMaxNodeId ? drive_of_node_[kind.node_id] : std::int16_t{-1};
  switch (kind.kind) {
    case co::FrameKind::tpdo: {
      if (index < 0) break;
      Drive& drive = drives_[static_cast<std::size_t>(index)];
      ++diagnostics_.tpdo_received;
      const PdoLayout& layout = pdo_layout();
      std::array<std::int64_t, 3> values{};
      if (kind.pdo_number == 1 && layout.tpdo1.check_length(frame) == co::PdoLength::ok &&
          layout.tpdo1.unpack(frame, values)) {
        drive.statusword = static_cast<std::uint16_t>(values[0]);
        drive.position_counts = static_cast<std::int32_t>(values[1]);
        drive.torque_actual_permille = static_cast<std::int16_t>(values[2]);
        drive.tpdo1_seen = true;
        drive.tpdo1_sync = syncs_sent_;
        const co::PowerState power = co::decode_statusword(drive.statusword);
        if (power == co::PowerState::fault || power == co::PowerState::fault_reaction_active) {
          latch(CanFault::drive_fault, drive.node);
        }
      } else if (kind.pdo_number == 2 &&
                 layout.tpdo2.check_length(frame) == co::PdoLength::ok &&
                 layout.tpdo2.unpack(frame, std::span(values.data(), 2))) {
        drive.velocity_actual = static_cast<std::int32_t>(values[0]);
        drive.digital_inputs = static_cast<std::uint32_t>(values[1]);
        drive.tpdo2_seen = true;
        drive.tpdo2_sync = syncs_sent_;
      } else {
        // A PDO of another length than its mapping: a node that is not configured as we
        // configured it, or a damaged frame (CiA 301 treats too short as an error).
        ++diagnostics_.frames_rejected;
        latch(CanFault::bad_pdo, drive.node);
      }
      break;
    }
    case co::FrameKind::emcy: {
      const auto emcy = co::decode_emcy(frame);
      if (!emcy) {
        ++diagnostics_.frames_rejected;
        break;
      }
      ++diagnostics_.emcy_received;
      // Error code 0x0000 is "error reset / no error": a drive announcing it recovered.
      if (emcy->error_code != 0 && index >= 0) {
        if (diagnostics_.first_emcy_code == 0) {
          diagnostics_.first_emcy_code = emcy->error_code;
          diagnostics_.first_emcy_register = emcy->error_register;
        }
        latch(CanFault::emcy, emcy->node_id);
      }
      break;
    }
    case co::FrameKind::heartbeat: {
      ++diagnostics_.heartbeats_received;
      (void)heartbeats_.on_frame(frame, now_ns);
      const auto beat = co::decode_heartbeat(frame);
      if (beat && index >= 0 && rt_started_) {
        if (beat->state == co::NmtState::boot_up) {
          latch(CanFault::node_rebooted, beat->node_id);
        } else if (beat->state != co::NmtState::operational) {
          latch(CanFault::node_not_operational, beat->node_id);
        }
      }
      break;
    }
    default:
      break;  // SDO answers arrive only at setup; our own frames are not echoed
  }
}

void CanopenDevice::drain_bus(std::int64_t now_ns) noexcept {
  std::array<can_frame, kMaxFramesPerCall> frames{};
  std::size_t drained = 0;
  while (drained < kMaxFramesPerCycle) {
    const std::size_t room = std::min(frames.size(), kMaxFramesPerCycle - drained);
    const std::size_t count = transport_->receive(std::span(frames.data(), room));
    for (std::size_t i = 0; i < count; ++i) handle_frame(frames[i], now_ns);
    drained += count;
    if (count < room) break;
  }
  if (drained >= kMaxFramesPerCycle) ++diagnostics_.cycles_frame_budget_hit;
  heartbeats_.on_time(now_ns);
  while (const auto event = heartbeats_.next_event()) {
    if (event->event == co::HeartbeatEvent::timed_out) latch(CanFault::heartbeat_lost, event->node_id);
  }
  diagnostics_.transport = transport_->counters();
}

hal::ReturnCode CanopenDevice::read_encoders(std::span<hal::EncoderSample> out) noexcept {
  if (state_ != hal::LifecycleState::active || out.size() < drives_.size()) {
    return hal::ReturnCode::error;
  }
  if (!rt_started_) {
    rt_started_ = true;
    next_heartbeat_ns_ = clock_.now_ns();
  }
  drain_bus(clock_.now_ns());
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    const Drive& drive = drives_[i];
    hal::EncoderSample& sample = out[i];
    const std::uint64_t age = drive.tpdo1_seen ? syncs_sent_ - drive.tpdo1_sync : syncs_sent_;
    const bool fresh = drive.tpdo1_seen && age <= params_.max_pdo_age_syncs;
    sample.counts = drive.position_counts;
    sample.position =
        static_cast<float>(params_.drives[i].scale.position_from_counts(drive.position_counts));
    sample.valid = fresh;
    if (!fresh) latch(CanFault::pdo_timeout, drive.node);
    if (age > 0) ++diagnostics_.stale_samples;
  }
  return latched() ? hal::ReturnCode::deactivate : hal::ReturnCode::ok;
}

hal::ReturnCode CanopenDevice::read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept {
  if (state_ == hal::LifecycleState::unconfigured || out.size() < drives_.size()) {
    return hal::ReturnCode::error;
  }
  bool any_fault = false;
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    const Drive& drive = drives_[i];
    const co::PowerState power = co::decode_statusword(drive.statusword);
    hal::ActuatorStatus& status = out[i];
    status.enabled = power == co::PowerState::operation_enabled;
    status.applied_effort =
        status.enabled ? static_cast<float>(drive.torque_actual_permille * drive.effort_per_permille *
                                            params_.drives[i].scale.motor_sign())
                       : 0.0F;
    status.saturated = drive.saturated;
    status.fault =
        power == co::PowerState::fault || power == co::PowerState::fault_reaction_active;
    any_fault = any_fault || status.fault;
  }
  if (state_ == hal::LifecycleState::active && (latched() || any_fault)) {
    return hal::ReturnCode::deactivate;
  }
  return hal::ReturnCode::ok;
}

hal::ReturnCode CanopenDevice::read_digital_inputs(std::uint32_t& levels) noexcept {
  if (state_ != hal::LifecycleState::active || params_.digital_inputs_node <= 0) {
    return hal::ReturnCode::error;
  }
  const Drive& drive = drives_[static_cast<std::size_t>(
      drive_of_node_[static_cast<std::size_t>(params_.digital_inputs_node)])];
  if (!drive.tpdo2_seen || syncs_sent_ - drive.tpdo2_sync > params_.max_pdo_age_syncs) {
    return hal::ReturnCode::error;  // the app then treats the e-stop as pressed
  }
  // CiA 402 0x60FD: bits 16..31 are the manufacturer's inputs, where the trainer's switches
  // are wired.
  levels = drive.digital_inputs >> 16;
  return hal::ReturnCode::ok;
}

hal::ReturnCode CanopenDevice::write_digital_outputs(std::uint32_t levels) noexcept {
  if (state_ != hal::LifecycleState::active || params_.digital_outputs_node <= 0 ||
      (levels >> 16) != 0U) {
    return hal::ReturnCode::error;
  }
  digital_outputs_ = levels;
  return hal::ReturnCode::ok;
}

std::uint16_t CanopenDevice::next_controlword(const Drive& drive, bool enable) const noexcept {
  if (latched()) return co::kCommandQuickStop;
  const co::PowerState power = co::decode_statusword(drive.statusword);
  return co::next_controlword(
      power, enable ? co::PowerTarget::operation_enabled : co::PowerTarget::disabled,
      drive.controlword);
}

hal::ReturnCode CanopenDevice::write_actuators(
    std::span<const hal::ActuatorCommand> commands) noexcept {
  if (state_ != hal::LifecycleState::active || commands.size() < drives_.size()) {
    return hal::ReturnCode::error;
  }
  if (!rt_started_) {
    rt_started_ = true;
    next_heartbeat_ns_ = clock_.now_ns();
  }
  bool rejected = false;
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    Drive& drive = drives_[i];
    const hal::ActuatorCommand& command = commands[i];
    const bool finite = std::isfinite(command.effort);
    rejected = rejected || !finite;
    const bool enable = command.enable && finite && !latched();
    drive.controlword = next_controlword(drive, enable);
    // motor_direction -1: the motor turns the joint negative for a positive torque.
    double permille = enable ? static_cast<double>(command.effort) / drive.effort_per_permille *
                                   params_.drives[i].scale.motor_sign()
                             : 0.0;
    const auto limit = static_cast<double>(drive.max_torque_permille);
    drive.saturated = std::fabs(permille) > limit;
    permille = std::clamp(permille, -limit, limit);
    drive.target_permille = static_cast<std::int16_t>(std::lround(permille));
  }
  ++cycles_;
  // SYNC (with the commands) on cycles 1, 1 + n, 1 + 2n ... for a SYNC every n loop periods.
  if ((cycles_ - 1) % sync_every_cycles_ == 0) send_cycle_frames(clock_.now_ns());
  if (latched()) return hal::ReturnCode::deactivate;
  return rejected ? hal::ReturnCode::error : hal::ReturnCode::ok;
}

void CanopenDevice::send_cycle_frames(std::int64_t now_ns) noexcept {
  std::array<can_frame, kMaxDrives + 4> frames{};
  std::size_t count = 0;
  const PdoLayout& layout = pdo_layout();
  for (const Drive& drive : drives_) {
    const std::array<std::int64_t, 2> values{drive.controlword, drive.target_permille};
    frames[count++] = rpdo_frame(layout.rpdo1, 1, drive.node, values);
  }
  if (params_.digital_outputs_node > 0) {
    const std::array<std::int64_t, 1> outputs{std::int64_t{digital_outputs_} << 16};
    frames[count++] = rpdo_frame(layout.rpdo2, 2,
                                 static_cast<std::uint8_t>(params_.digital_outputs_node), outputs);
  }
  frames[count++] = co::encode_sync();
  if (now_ns >= next_heartbeat_ns_) {
    frames[count++] = co::encode_heartbeat(params_.master_node_id, co::NmtState::operational);
    next_heartbeat_ns_ += params_.master_heartbeat_ns;
    if (next_heartbeat_ns_ < now_ns) next_heartbeat_ns_ = now_ns + params_.master_heartbeat_ns;
  }
  const std::size_t sent = transport_->send(std::span(frames.data(), count));
  diagnostics_.rpdo_sent += std::min(sent, drives_.size());
  // The SYNC counts as sent only when the kernel took it: the PDO age is counted in SYNCs.
  if (sent > drives_.size() + (params_.digital_outputs_node > 0 ? 1U : 0U)) {
    ++syncs_sent_;
    ++diagnostics_.sync_sent;
  }
  diagnostics_.transport = transport_->counters();
}

// ------------------------------------------------------------------------------ lifecycle

core::Expected<void> CanopenDevice::configure() {
  if (state_ == hal::LifecycleState::active) {
    return core::make_error(params_.name + ": configure() while active: deactivate first");
  }
  if (auto checked = check_params(); !checked) return checked;
  diagnostics_.bus_load = estimate_bus_load(params_);
  sync_every_cycles_ = static_cast<std::uint32_t>(params_.sync_period_ns / params_.loop_period_ns);
  if (!transport_) {
    // One receive filter per drive: every function code of that node id (TPDOs, EMCY, SDO
    // answers, heartbeat), nothing of other nodes; error frames come through the error mask.
    std::vector<CanFilter> filters;
    for (const DriveParams& drive : params_.drives) {
      filters.push_back(CanFilter{drive.node_id, CAN_EFF_FLAG | CAN_RTR_FLAG | 0x7FU});
    }
    auto opened = CanTransport::open_socketcan(params_.interface, filters);
    if (!opened) return core::make_error(params_.name + ": " + opened.error().message);
    transport_.emplace(std::move(*opened));
  }
  drive_of_node_.fill(-1);
  drives_.assign(params_.drives.size(), Drive{});
  for (std::size_t i = 0; i < params_.drives.size(); ++i) {
    const DriveParams& p = params_.drives[i];
    Drive& drive = drives_[i];
    drive.node = p.node_id;
    drive_of_node_[p.node_id] = static_cast<std::int16_t>(i);
    // Joint-side effort per per-mille of rated motor torque: the motor torque goes through
    // the gear (and capstan) like the current does in JointScale::effort_per_amp().
    drive.effort_per_permille =
        p.motor_rated_torque_nm * 1e-3 * p.scale.effort_per_amp() / p.scale.torque_constant_nm_per_a;
    drive.max_torque_permille = static_cast<std::int32_t>(std::floor(
        p.scale.current_limit_a * p.scale.torque_constant_nm_per_a / p.motor_rated_torque_nm *
        1000.0));
    drive.max_torque_permille = std::clamp(drive.max_torque_permille, 1, 32767);
  }
  detail::SetupBus bus(*transport_, transport_->name(), params_.sdo_timeout_ns);
  if (auto booted = detail::reset_and_wait_for_boot(bus, params_); !booted) {
    state_ = hal::LifecycleState::unconfigured;
    return booted;
  }
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    auto configured = detail::configure_drive(bus, params_, i, drives_[i].max_torque_permille);
    if (!configured) {
      state_ = hal::LifecycleState::unconfigured;
      return configured;
    }
  }
  state_ = hal::LifecycleState::inactive;
  return {};
}

core::Expected<void> CanopenDevice::activate() {
  if (state_ != hal::LifecycleState::inactive) {
    return core::make_error(params_.name + ": activate() needs a configured, inactive device");
  }
  detail::SetupBus bus(*transport_, transport_->name(), params_.sdo_timeout_ns);
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    if (auto cleared = detail::clear_drive_fault(bus, params_, i); !cleared) return cleared;
  }
  reset_rt_state();
  // NMT start, then one SYNC so that every drive's TPDOs are in before the first RT cycle
  // reads them (no RPDO and no master heartbeat yet: the drives' deadline monitoring starts
  // with those, in the first RT cycle).
  for (const Drive& drive : drives_) {
    if (!transport_->send_one(co::encode_nmt(co::NmtCommand::start, drive.node))) {
      return core::make_error(params_.name + ": NMT start could not be sent on " +
                              transport_->name());
    }
  }
  if (!transport_->send_one(co::encode_sync())) {
    return core::make_error(params_.name + ": SYNC could not be sent on " + transport_->name());
  }
  ++syncs_sent_;
  ++diagnostics_.sync_sent;
  const auto all_in = [this] {
    return std::all_of(drives_.begin(), drives_.end(), [this](const Drive& drive) {
      return drive.tpdo1_seen && (drive.node != params_.digital_inputs_node || drive.tpdo2_seen);
    });
  };
  detail::SetupBus wait(*transport_, transport_->name(), params_.sdo_timeout_ns);
  (void)wait.wait_for(params_.boot_timeout_ns, [&](const can_frame& frame) {
    handle_frame(frame, clock_.now_ns());
    return all_in();
  });
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    if (drives_[i].tpdo1_seen) continue;
    return core::make_error(detail::drive_who(params_, i) +
                            ": no TPDO1 (statusword, position) after NMT start and a SYNC within " +
                            std::to_string(params_.boot_timeout_ns / 1'000'000) +
                            " ms (canopen.boot_timeout_ms): the PDO configuration did not take");
  }
  if (latched()) {
    return core::make_error(params_.name + ": fault while starting the drives: " + fault_report());
  }
  diagnostics_.transport = transport_->counters();
  state_ = hal::LifecycleState::active;
  return {};
}

void CanopenDevice::deactivate() noexcept {
  if (state_ == hal::LifecycleState::unconfigured || !transport_) {
    return;
  }
  std::array<can_frame, kMaxDrives + 3> frames{};
  std::size_t count = 0;
  for (const Drive& drive : drives_) {
    const std::array<std::int64_t, 2> values{co::kCommandDisableVoltage, 0};
    frames[count++] = rpdo_frame(pdo_layout().rpdo1, 1, drive.node, values);
  }
  frames[count++] = co::encode_sync();
  frames[count++] = co::encode_nmt(co::NmtCommand::enter_pre_operational, 0);
  (void)transport_->send(std::span(frames.data(), count));
  diagnostics_.transport = transport_->counters();
  if (state_ == hal::LifecycleState::active) state_ = hal::LifecycleState::inactive;
}

core::Expected<void> CanopenDevice::refresh_status() {
  if (state_ != hal::LifecycleState::inactive || !transport_) {
    return core::make_error(params_.name + ": refresh_status() needs a configured, inactive device");
  }
  detail::SetupBus bus(*transport_, transport_->name(), params_.sdo_timeout_ns);
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    Drive& drive = drives_[i];
    const std::string who = detail::drive_who(params_, i);
    auto status = bus.read(who, drive.node, co::kObjectStatusword, 0);
    if (!status) return std::move(status).error();
    auto torque = bus.read(who, drive.node, co::kObjectTorqueActual, 0);
    if (!torque) return std::move(torque).error();
    drive.statusword = static_cast<std::uint16_t>(*status);
    drive.torque_actual_permille = static_cast<std::int16_t>(static_cast<std::uint16_t>(*torque));
  }
  diagnostics_.transport = transport_->counters();
  return {};
}

std::string CanopenDevice::fault_report() const {
  std::string text;
  for (std::uint32_t bit = 1; bit <= static_cast<std::uint32_t>(CanFault::bad_pdo); bit <<= 1U) {
    if ((diagnostics_.faults & bit) == 0U) continue;
    const auto fault = static_cast<CanFault>(bit);
    if (!text.empty()) text += "; ";
    text += to_string(fault);
    if (fault == diagnostics_.first_fault && diagnostics_.first_fault_node != 0) {
      const std::int16_t index = drive_of_node_[diagnostics_.first_fault_node];
      text += " (first: node " + std::to_string(diagnostics_.first_fault_node);
      if (index >= 0) text += ", " + params_.drives[static_cast<std::size_t>(index)].channel_name;
      text += ")";
    }
    if (fault == CanFault::emcy) {
      char code[96];
      std::snprintf(code, sizeof code, " EMCY 0x%04X %s, error register 0x%02X",
                    diagnostics_.first_emcy_code, co::describe_emcy_code(diagnostics_.first_emcy_code),
                    diagnostics_.first_emcy_register);
      text += code;
    }
  }
  return text;
}

}  // namespace trainer::hal::socketcan
