// SimDriveNode at run time: frames (NMT, SDO, RPDO, heartbeats), the SYNC cycle (RPDOs applied,
// power state machine, actual values, TPDOs), timers (heartbeat production and consumption,
// RPDO deadlines, event-driven TPDOs), the torque, the statusword and EMCYs. No heap, no
// system calls: frames go to the node's queue, which the bus sends.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/objects.hpp"
#include "trainer/hal_canopen/pdo_dictionary.hpp"
#include "trainer/hal_simdrive/sim_drive_node.hpp"

namespace trainer::hal::simdrive {

namespace co = trainer::hal::canopen;

namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;
constexpr std::int64_t kNsPer100Us = 100'000;
constexpr std::int64_t kNoDeadline = std::numeric_limits<std::int64_t>::max();
// CiA 301 Table 21: communication, generic; used as the error code when an NMT command takes
// the master away (0x6007 option 1 then faults with it).
constexpr std::uint16_t kEmcyCommunicationGeneric = 0x8100;
constexpr std::uint16_t kObjectDigitalInputsCycle = 0x60FD;
constexpr std::int8_t kModeCstCycle =
    static_cast<std::int8_t>(co::OperationMode::cyclic_synchronous_torque);

bool maps_object(const co::PdoMapping& mapping, std::uint16_t index) noexcept {
  for (const co::PdoField& field : mapping.fields()) {
    if (field.object.index == index) return true;
  }
  return false;
}

std::uint8_t error_class_bits(std::uint16_t code) noexcept {
  if ((code >> 8) == 0xFF) return co::kErrorRegisterManufacturer;
  switch (code >> 12) {
    case 0x2: return co::kErrorRegisterCurrent;
    case 0x3: return co::kErrorRegisterVoltage;
    case 0x4: return co::kErrorRegisterTemperature;
    case 0x8: return co::kErrorRegisterCommunication;
    default: return 0;
  }
}

}  // namespace

// ------------------------------------------------------------------------------ output

void SimDriveNode::queue(const can_frame& frame, TxKind kind, std::uint8_t pdo_number,
                         const char* cause) noexcept {
  if (!tx_.push_back(TxFrame{frame, kind, pdo_number, cause})) ++counters_.tx_overflows;
}

void SimDriveNode::log(EventKind kind, std::uint32_t a, std::uint32_t b, const char* cause,
                       const char* text) noexcept {
  DriveEvent event;
  event.t_ns = now_.now_ns;
  event.sync = now_.sync;
  event.node = params_.node_id;
  event.kind = kind;
  event.a = a;
  event.b = b;
  event.cause = cause;
  if (text != nullptr) std::strncpy(event.text.data(), text, event.text.size() - 1);
  (void)events_.push(event);
}

std::uint8_t SimDriveNode::error_register() const noexcept {
  std::uint8_t value = 0;
  const co::PowerState state = power_.state();
  if (state == co::PowerState::fault || state == co::PowerState::fault_reaction_active) {
    value = static_cast<std::uint8_t>(value | co::kErrorRegisterGeneric |
                                      error_class_bits(power_.error_code()));
  }
  if (heartbeat_lost_ || rpdo_timed_out_) {
    value = static_cast<std::uint8_t>(value | co::kErrorRegisterGeneric |
                                      co::kErrorRegisterCommunication);
  }
  return value;
}

void SimDriveNode::send_emcy(std::uint16_t code, const char* cause) noexcept {
  ++counters_.emcys;
  publish_status();
  const std::uint8_t reg = error_register();
  if (!nmt_.emcy_allowed()) {
    log(EventKind::emcy_sent, code, reg, cause, "suppressed: NMT stopped");
    return;
  }
  queue(co::encode_emcy({params_.node_id, code, reg, {}}), TxKind::emcy, 0, cause);
}

void SimDriveNode::publish_status() noexcept {
  power_.set_warning(heartbeat_lost_ || rpdo_timed_out_);
  const std::int64_t mode = od_.get_int(co::kObjectModesOfOperation, 0).value_or(0);
  (void)od_.set<std::uint16_t>(co::kObjectStatusword, 0, power_.statusword());
  (void)od_.set<std::uint16_t>(co::kObjectErrorCode, 0, power_.error_code());
  (void)od_.set<std::int8_t>(co::kObjectModesOfOperationDisplay, 0,
                             mode == kModeCstCycle ? kModeCstCycle : 0);
  (void)od_.set<std::int16_t>(co::kObjectTorqueActual, 0, torque_actual_permille_);
  (void)od_.set<std::uint8_t>(co::kObjectErrorRegister, 0, error_register());
}

void SimDriveNode::refresh_torque() noexcept {
  const std::int64_t mode = od_.get_int(co::kObjectModesOfOperation, 0).value_or(0);
  const auto target = static_cast<double>(od_.get_int(co::kObjectTargetTorque, 0).value_or(0));
  const auto max_permille = static_cast<double>(od_.get_int(co::kObjectMaxTorque, 0).value_or(0));
  bool limited = false;
  double commanded = 0.0;
  if (mode == kModeCstCycle) {
    limited = std::fabs(target) > max_permille;
    commanded = std::clamp(target, -max_permille, max_permille);
  }
  const double applied_permille = power_.torque_output(commanded);
  const hal::JointScale& scale = params_.scale;
  const double motor_torque_nm =
      applied_permille * static_cast<double>(params_.motor_rated_torque_mnm) * 1e-6;
  double current_a = motor_torque_nm / scale.torque_constant_nm_per_a;
  if (std::fabs(current_a) > scale.current_limit_a) {
    limited = true;
    current_a = std::clamp(current_a, -scale.current_limit_a, scale.current_limit_a);
  }
  power_.set_internal_limit_active(limited);
  torque_actual_permille_ = co::torque_to_permille(current_a * scale.torque_constant_nm_per_a,
                                                   params_.motor_rated_torque_mnm);
  const double motor_sign = params_.reverse_motor ? -1.0 : 1.0;
  const DriveOutput next{current_a * scale.effort_per_amp() * motor_sign,
                         power_.drive_function_enabled()};
  if (next.effort != output_.effort || next.enabled != output_.enabled) {
    output_ = next;
    output_changed_ = true;
  }
}

// ------------------------------------------------------------------------------ power

void SimDriveNode::after_power_change(co::PowerState before, bool drive_was_on,
                                      const char* cause) noexcept {
  const co::PowerState after = power_.state();
  if (before != after)
    log(EventKind::power_state, static_cast<std::uint32_t>(before),
        static_cast<std::uint32_t>(after), cause);
  refresh_torque();
  publish_status();
  const bool drive_on = power_.drive_function_enabled();
  if (drive_was_on && !drive_on) log(EventKind::torque_removed, 0, 0, cause);
  if (!drive_was_on && drive_on) log(EventKind::torque_enabled, 0, 0, cause);
  // A fault reset (transition 15) is announced with the "error reset / no error" EMCY.
  if (before == co::PowerState::fault && after == co::PowerState::switch_on_disabled)
    send_emcy(co::kEmcyNoError, cause);
}

void SimDriveNode::power_update(std::uint16_t controlword, const char* cause) noexcept {
  const co::PowerState before = power_.state();
  const bool was_on = power_.drive_function_enabled();
  power_.update(controlword, now_.now_ns);
  after_power_change(before, was_on, cause);
}

void SimDriveNode::power_connection_lost(std::uint16_t error_code, const char* cause) noexcept {
  const auto option =
      static_cast<std::uint32_t>(od_.get_int(co::kObjectAbortConnectionOption, 0).value_or(0));
  log(EventKind::abort_connection, option, 0, cause);
  const co::PowerState before = power_.state();
  const bool was_on = power_.drive_function_enabled();
  power_.connection_lost(error_code, now_.now_ns);
  after_power_change(before, was_on, cause);
}

void SimDriveNode::power_fault(std::uint16_t error_code, const char* cause) noexcept {
  const co::PowerState before = power_.state();
  const bool was_on = power_.drive_function_enabled();
  power_.raise_fault(error_code, now_.now_ns);
  after_power_change(before, was_on, cause);
}

void SimDriveNode::inject_emcy(std::uint16_t code, std::int64_t now_ns,
                               std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  power_.set_fault_present(false);  // the master's fault reset clears it
  power_fault(code, "EMCY injected");
  send_emcy(code, "EMCY injected");
}

void SimDriveNode::bus_off(std::int64_t now_ns, std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  // No EMCY: a node that is off the bus cannot send one.
  power_connection_lost(co::kEmcyRecoveredFromBusOff, "bus-off");
}

// ------------------------------------------------------------------------------ frames

bool SimDriveNode::on_frame(const can_frame& frame, std::int64_t now_ns,
                            std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  if (co::is_error_frame(frame) || co::is_extended(frame) || co::is_remote(frame) ||
      nmt_.initialising()) {
    return false;
  }
  const std::uint16_t id = co::frame_id(frame);
  if (nmt_.pdo_allowed()) {
    for (std::size_t i = 0; i < kPdoCount; ++i) {
      if (rpdo_[i].valid && rpdo_[i].can_id == id) {
        ++counters_.frames_received;
        handle_rpdo(i, frame);
        return true;
      }
    }
  }
  const co::FrameClass kind = co::classify(frame);
  switch (kind.kind) {
    case co::FrameKind::nmt: {
      if (!kind.ok() || (frame.data[1] != 0 && frame.data[1] != params_.node_id)) return false;
      ++counters_.frames_received;
      handle_nmt(frame);
      return true;
    }
    case co::FrameKind::sync:
      // Valid SYNCs come through on_sync(); this one has a length CiA 301 does not allow.
      if (kind.ok() || !nmt_.sync_allowed()) return false;
      ++counters_.frames_received;
      if (!sync_length_reported_) {
        sync_length_reported_ = true;
        send_emcy(co::kEmcyUnexpectedSyncLength, "SYNC of a wrong length");
      }
      return true;
    case co::FrameKind::sdo_request: {
      if (kind.node_id != params_.node_id || !kind.ok()) return false;
      ++counters_.frames_received;
      ++counters_.sdo_requests;
      if (!nmt_.sdo_allowed()) return true;  // stopped: no SDO
      const std::uint32_t aborts_before = sdo_.aborts_sent();
      (void)sdo_.on_frame(frame, now_ns);
      counters_.sdo_aborts += sdo_.aborts_sent() - aborts_before;
      while (const auto response = sdo_.next_tx()) queue(*response, TxKind::sdo);
      return true;
    }
    case co::FrameKind::heartbeat: {
      if (!kind.ok()) return false;
      const co::NodeHeartbeatStatus* status = consumer_.status(kind.node_id);
      if (status == nullptr) return false;
      const co::NodeHealth before = status->health;
      if (!consumer_.on_frame(frame, now_ns)) return false;
      ++counters_.frames_received;
      if ((before == co::NodeHealth::not_seen || before == co::NodeHealth::booted) &&
          status->health == co::NodeHealth::alive) {
        log(EventKind::master_heartbeat_seen, kind.node_id, status->consumer_time_ms);
      }
      handle_heartbeat_events();
      return true;
    }
    default: return false;
  }
}

void SimDriveNode::handle_nmt(const can_frame& frame) noexcept {
  const co::NmtState before = nmt_.state();
  const bool drive_on = power_.drive_function_enabled();
  switch (nmt_.on_frame(frame)) {
    case co::NmtEvent::none: return;
    case co::NmtEvent::state_changed: {
      const co::NmtState after = nmt_.state();
      log(EventKind::nmt_state, static_cast<std::uint32_t>(before),
          static_cast<std::uint32_t>(after), "NMT command");
      reset_pdo_runtime();  // PDOs start afresh in operational; latched data and deadlines go
      rpdo_timed_out_ = false;
      // CiA 402 0x6007 lists "NMT stopped" among the events that lose the connection.
      if (after == co::NmtState::stopped && drive_on)
        power_connection_lost(kEmcyCommunicationGeneric, "NMT stop");
      publish_status();
      return;
    }
    case co::NmtEvent::reset_application:
      if (drive_on) power_connection_lost(kEmcyCommunicationGeneric, "NMT reset node");
      reset_application("NMT reset node");
      return;
    case co::NmtEvent::reset_communication:
      if (drive_on) power_connection_lost(kEmcyCommunicationGeneric, "NMT reset communication");
      reset_communication();
      return;
  }
}

void SimDriveNode::handle_rpdo(std::size_t index, const can_frame& frame) noexcept {
  RpdoState& rpdo = rpdo_[index];
  if (rpdo.mapping.size() == 0) return;  // mapping disabled: nothing to take
  if (rpdo.mapping.check_length(frame) == co::PdoLength::too_short) {
    ++counters_.rpdo_length_errors;
    if (!rpdo.length_error_reported) {
      rpdo.length_error_reported = true;
      send_emcy(co::kEmcyPdoLengthError, "RPDO shorter than its mapping");
    }
    return;  // CiA 301: not processed
  }
  rpdo.length_error_reported = false;
  ++counters_.rpdos;
  if (rpdo.event_timer_ms > 0) {
    rpdo.deadline_armed = true;
    rpdo.deadline_ns = now_.now_ns + static_cast<std::int64_t>(rpdo.event_timer_ms) * kNsPerMs;
  }
  if (rpdo_timed_out_) {
    rpdo_timed_out_ = false;
    publish_status();
  }
  if (co::is_synchronous_transmission(rpdo.transmission_type)) {
    rpdo.latched = true;  // applied at the next SYNC
    rpdo.latched_frame = frame;
    return;
  }
  (void)co::unpack_to_dictionary(rpdo.mapping, frame, od_);
  if (maps_object(rpdo.mapping, co::kObjectControlword)) {
    power_update(static_cast<std::uint16_t>(od_.get_int(co::kObjectControlword, 0).value_or(0)),
                 "controlword (RPDO)");
  } else {
    refresh_torque();
    publish_status();
  }
}

void SimDriveNode::handle_heartbeat_events() noexcept {
  while (const auto event = consumer_.next_event()) {
    const co::NodeHeartbeatStatus* status = consumer_.status(event->node_id);
    const std::uint32_t time_ms = status != nullptr ? status->consumer_time_ms : 0;
    switch (event->event) {
      case co::HeartbeatEvent::timed_out:
        heartbeat_lost_ = true;
        log(EventKind::master_heartbeat_lost, event->node_id, time_ms);
        power_connection_lost(co::kEmcyHeartbeatError, "master heartbeat lost");
        send_emcy(co::kEmcyHeartbeatError, "master heartbeat lost");
        break;
      case co::HeartbeatEvent::recovered:
        heartbeat_lost_ = false;
        log(EventKind::master_heartbeat_recovered, event->node_id, time_ms);
        if (!rpdo_timed_out_ && power_.state() != co::PowerState::fault) {
          send_emcy(co::kEmcyNoError, "master heartbeat recovered");
        }
        publish_status();
        break;
      default: break;  // boot-up / state change of the master: nothing to do for a drive
    }
  }
}

// ------------------------------------------------------------------------------ SYNC

void SimDriveNode::on_sync(const PlantSample& sample, std::int64_t now_ns,
                           std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  if (!nmt_.sync_allowed()) return;  // stopped: nothing but NMT
  ++counters_.syncs;
  sync_length_reported_ = false;
  bool controlword_from_rpdo = false;
  if (nmt_.pdo_allowed()) {
    for (RpdoState& rpdo : rpdo_) {
      if (!rpdo.latched) continue;
      rpdo.latched = false;
      (void)co::unpack_to_dictionary(rpdo.mapping, rpdo.latched_frame, od_);
      controlword_from_rpdo =
          controlword_from_rpdo || maps_object(rpdo.mapping, co::kObjectControlword);
    }
  }
  // Actual values at the SYNC instant (a 32-bit position wraps as a real encoder's does).
  const double encoder_sign = params_.reverse_encoder ? -1.0 : 1.0;
  const std::int64_t counts =
      (params_.reverse_encoder ? -sample.position_counts : sample.position_counts) +
      encoder_offset_counts_;
  (void)od_.set<std::int32_t>(
      co::kObjectPositionActual, 0,
      static_cast<std::int32_t>(static_cast<std::uint32_t>(counts & 0xFFFFFFFF)));
  const double velocity = std::clamp(std::round(sample.velocity_counts_per_s * encoder_sign),
                                     static_cast<double>(std::numeric_limits<std::int32_t>::min()),
                                     static_cast<double>(std::numeric_limits<std::int32_t>::max()));
  (void)od_.set<std::int32_t>(co::kObjectVelocityActual, 0, static_cast<std::int32_t>(velocity));
  (void)od_.set<std::uint32_t>(kObjectDigitalInputsCycle, 0, sample.digital_inputs);
  // The drive's cycle: one step of the power state machine with the controlword in force.
  power_update(static_cast<std::uint16_t>(od_.get_int(co::kObjectControlword, 0).value_or(0)),
               controlword_from_rpdo ? "controlword (RPDO)" : "drive cycle");
  if (!nmt_.pdo_allowed()) return;
  for (std::size_t i = 0; i < kPdoCount; ++i) {
    TpdoState& tpdo = tpdo_[i];
    if (!tpdo.valid || !co::is_synchronous_transmission(tpdo.transmission_type)) continue;
    if (tpdo.transmission_type == co::kTransmissionSynchronousAcyclic) {
      send_tpdo(i, true);
    } else if (++tpdo.sync_counter >= tpdo.transmission_type) {
      tpdo.sync_counter = 0;
      send_tpdo(i, false);
    }
  }
}

void SimDriveNode::send_tpdo(std::size_t index, bool only_if_changed) noexcept {
  TpdoState& tpdo = tpdo_[index];
  if (tpdo.mapping.size() == 0) return;
  can_frame frame = co::make_frame(tpdo.can_id, {});
  if (!co::pack_from_dictionary(tpdo.mapping, od_, frame)) return;
  const bool same = tpdo.sent_once && frame.len == tpdo.last_length &&
                    std::equal(frame.data, frame.data + frame.len, tpdo.last_data.begin());
  if (only_if_changed && same) return;
  queue(frame, TxKind::tpdo, static_cast<std::uint8_t>(index + 1));
  ++counters_.tpdos;
  tpdo.sent_once = true;
  tpdo.last_length = frame.len;
  std::copy(frame.data, frame.data + CAN_MAX_DLEN, tpdo.last_data.begin());
  tpdo.last_sent_ns = now_.now_ns;
  tpdo.next_event_ns = now_.now_ns + static_cast<std::int64_t>(tpdo.event_timer_ms) * kNsPerMs;
}

// ------------------------------------------------------------------------------ timers

void SimDriveNode::check_rpdo_deadlines() noexcept {
  if (!nmt_.pdo_allowed()) return;
  for (std::size_t i = 0; i < kPdoCount; ++i) {
    RpdoState& rpdo = rpdo_[i];
    if (!rpdo.valid || !rpdo.deadline_armed || now_.now_ns <= rpdo.deadline_ns) continue;
    rpdo.deadline_armed = false;  // armed again by the next RPDO
    rpdo_timed_out_ = true;
    log(EventKind::rpdo_deadline_expired, static_cast<std::uint32_t>(i + 1), rpdo.event_timer_ms);
    power_connection_lost(co::kEmcyRpdoTimeout, "RPDO deadline");
    send_emcy(co::kEmcyRpdoTimeout, "RPDO deadline");
  }
}

void SimDriveNode::check_event_tpdos() noexcept {
  for (std::size_t i = 0; i < kPdoCount; ++i) {
    TpdoState& tpdo = tpdo_[i];
    if (!tpdo.valid || !co::is_event_transmission(tpdo.transmission_type)) continue;
    const std::int64_t inhibit_ns = static_cast<std::int64_t>(tpdo.inhibit_100us) * kNsPer100Us;
    if (tpdo.sent_once && now_.now_ns < tpdo.last_sent_ns + inhibit_ns) continue;
    const bool timer_due = tpdo.event_timer_ms > 0 && now_.now_ns >= tpdo.next_event_ns;
    send_tpdo(i, !timer_due);
  }
}

void SimDriveNode::on_time(std::int64_t now_ns, std::uint64_t sync) noexcept {
  now_ = {now_ns, sync};
  if (nmt_.initialising()) return;
  if (heartbeat_period_ms_ > 0 && now_ns >= next_heartbeat_ns_) {
    queue(co::encode_heartbeat(params_.node_id, nmt_.state()), TxKind::heartbeat);
    ++counters_.heartbeats;
    const std::int64_t period_ns = static_cast<std::int64_t>(heartbeat_period_ms_) * kNsPerMs;
    next_heartbeat_ns_ += period_ns;
    if (next_heartbeat_ns_ <= now_ns) next_heartbeat_ns_ = now_ns + period_ns;
  }
  consumer_.on_time(now_ns);
  handle_heartbeat_events();
  check_rpdo_deadlines();
  if (nmt_.sdo_allowed()) {
    sdo_.on_time(now_ns);
    while (const auto response = sdo_.next_tx()) queue(*response, TxKind::sdo);
  }
  if (nmt_.pdo_allowed()) check_event_tpdos();
}

std::int64_t SimDriveNode::next_deadline_ns(std::int64_t now_ns) const noexcept {
  std::int64_t next = kNoDeadline;
  if (nmt_.initialising()) return next;
  if (heartbeat_period_ms_ > 0) next = std::min(next, next_heartbeat_ns_);
  for (std::uint8_t sub = 1; sub <= kConsumerHeartbeatEntries; ++sub) {
    const co::ConsumerEntry entry = co::decode_consumer_entry(
        static_cast<std::uint32_t>(od_.get_int(co::kObjectConsumerHeartbeatTime, sub).value_or(0)));
    const co::NodeHeartbeatStatus* status =
        entry.node_id != 0 ? consumer_.status(entry.node_id) : nullptr;
    if (status != nullptr && status->health == co::NodeHealth::alive) {
      next = std::min(next, status->last_heard_ns +
                                static_cast<std::int64_t>(status->consumer_time_ms) * kNsPerMs + 1);
    }
  }
  if (nmt_.pdo_allowed()) {
    for (const RpdoState& rpdo : rpdo_) {
      if (rpdo.valid && rpdo.deadline_armed) next = std::min(next, rpdo.deadline_ns + 1);
    }
    for (const TpdoState& tpdo : tpdo_) {
      if (!tpdo.valid || !co::is_event_transmission(tpdo.transmission_type)) continue;
      if (tpdo.event_timer_ms > 0) next = std::min(next, tpdo.next_event_ns);
      const std::int64_t inhibit_end =
          tpdo.last_sent_ns + static_cast<std::int64_t>(tpdo.inhibit_100us) * kNsPer100Us;
      if (tpdo.sent_once && inhibit_end > now_ns) next = std::min(next, inhibit_end);
    }
  }
  if (sdo_.busy()) next = std::min(next, now_ns + 10 * kNsPerMs);  // the server's segment timeout
  return next;
}

}  // namespace trainer::hal::simdrive
