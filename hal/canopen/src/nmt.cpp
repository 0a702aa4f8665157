// NMT commands and the slave state machine (CiA 301 v4.2, 7.2.8.2.1 and 7.3.2).
#include "trainer/hal_canopen/nmt.hpp"

#include "trainer/hal_canopen/frame.hpp"

namespace trainer::hal::canopen {

namespace {

bool is_defined_command(std::uint8_t value) noexcept {
  switch (value) {
    case static_cast<std::uint8_t>(NmtCommand::start):
    case static_cast<std::uint8_t>(NmtCommand::stop):
    case static_cast<std::uint8_t>(NmtCommand::enter_pre_operational):
    case static_cast<std::uint8_t>(NmtCommand::reset_node):
    case static_cast<std::uint8_t>(NmtCommand::reset_communication): return true;
    default: return false;
  }
}

}  // namespace

can_frame encode_nmt(NmtCommand command, std::uint8_t node_id) noexcept {
  const std::uint8_t data[2] = {static_cast<std::uint8_t>(command),
                                static_cast<std::uint8_t>(node_id & 0x7FU)};
  return make_frame(kCobNmt, data);
}

std::optional<NmtMessage> decode_nmt(const can_frame& frame) noexcept {
  if (!is_data_frame_with_id(frame, kCobNmt) || frame.len != 2) return std::nullopt;
  if (!is_defined_command(frame.data[0]) || frame.data[1] > kMaxNodeId) return std::nullopt;
  return NmtMessage{static_cast<NmtCommand>(frame.data[0]), frame.data[1]};
}

std::optional<NmtState> nmt_state_from_byte(std::uint8_t value) noexcept {
  switch (value) {
    case static_cast<std::uint8_t>(NmtState::boot_up):
    case static_cast<std::uint8_t>(NmtState::stopped):
    case static_cast<std::uint8_t>(NmtState::operational):
    case static_cast<std::uint8_t>(NmtState::pre_operational): return static_cast<NmtState>(value);
    default: return std::nullopt;
  }
}

can_frame NmtSlave::boot() noexcept {
  initialising_ = false;
  state_ = NmtState::pre_operational;
  const std::uint8_t data[1] = {static_cast<std::uint8_t>(NmtState::boot_up)};
  return make_frame(static_cast<std::uint16_t>(kCobHeartbeatBase + node_id_), data);
}

NmtEvent NmtSlave::on_frame(const can_frame& frame) noexcept {
  const auto message = decode_nmt(frame);
  if (!message || (message->node_id != 0 && message->node_id != node_id_)) return NmtEvent::none;
  return apply(message->command);
}

NmtEvent NmtSlave::apply(NmtCommand command) noexcept {
  // Resets are accepted in every state, also during initialisation (they restart it).
  if (command == NmtCommand::reset_node) {
    initialising_ = true;
    return NmtEvent::reset_application;
  }
  if (command == NmtCommand::reset_communication) {
    initialising_ = true;
    return NmtEvent::reset_communication;
  }
  // Initialisation passes to pre-operational by itself (boot()); no state command applies.
  if (initialising_) return NmtEvent::none;
  NmtState next = state_;
  switch (command) {
    case NmtCommand::start: next = NmtState::operational; break;
    case NmtCommand::stop: next = NmtState::stopped; break;
    case NmtCommand::enter_pre_operational: next = NmtState::pre_operational; break;
    default: break;
  }
  if (next == state_) return NmtEvent::none;
  state_ = next;
  return NmtEvent::state_changed;
}

bool NmtSlave::sdo_allowed() const noexcept {
  return !initialising_ && (state_ == NmtState::pre_operational || state_ == NmtState::operational);
}
bool NmtSlave::pdo_allowed() const noexcept {
  return !initialising_ && state_ == NmtState::operational;
}
bool NmtSlave::sync_allowed() const noexcept { return sdo_allowed(); }

const char* to_string(NmtCommand command) noexcept {
  switch (command) {
    case NmtCommand::start: return "start remote node";
    case NmtCommand::stop: return "stop remote node";
    case NmtCommand::enter_pre_operational: return "enter pre-operational";
    case NmtCommand::reset_node: return "reset node";
    case NmtCommand::reset_communication: return "reset communication";
  }
  return "?";
}

const char* to_string(NmtState state) noexcept {
  switch (state) {
    case NmtState::boot_up: return "boot-up";
    case NmtState::stopped: return "stopped";
    case NmtState::operational: return "operational";
    case NmtState::pre_operational: return "pre-operational";
  }
  return "?";
}

}  // namespace trainer::hal::canopen
