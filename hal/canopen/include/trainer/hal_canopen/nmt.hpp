// NMT (CiA 301 v4.2, 7.2.8): module control commands and the NMT slave state machine.
//
// Master side:
//   send(encode_nmt(NmtCommand::start, node));          // node 0 = all nodes
// Slave side (simulated drive):
//   NmtSlave nmt(node_id);
//   send(nmt.boot());                                   // boot-up message, now pre-operational
//   per received frame:
//     switch (nmt.on_frame(frame)) {
//       case NmtEvent::reset_application:   reset the manufacturer + profile OD area, then
//       case NmtEvent::reset_communication: reset the communication area (0x1000..0x1FFF);
//                                           send(nmt.boot());
//       ...
//     }
//   if (nmt.pdo_allowed()) { ...RPDO/TPDO... }          // only when operational
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <optional>

namespace trainer::hal::canopen {

// Command specifiers, byte 0 of the NMT frame (COB-ID 0x000, 2 bytes).
enum class NmtCommand : std::uint8_t {
  start = 0x01,                 // -> operational
  stop = 0x02,                  // -> stopped
  enter_pre_operational = 0x80,  // -> pre-operational
  reset_node = 0x81,            // application + communication reset, then boot-up
  reset_communication = 0x82,   // communication reset, then boot-up
};
const char* to_string(NmtCommand command) noexcept;

// States as the heartbeat reports them (byte 0 of the heartbeat, bit 7 = 0).
enum class NmtState : std::uint8_t {
  boot_up = 0x00,  // initialisation finished; sent once as the boot-up message
  stopped = 0x04,
  operational = 0x05,
  pre_operational = 0x7F,
};
const char* to_string(NmtState state) noexcept;
// The NmtState for a heartbeat byte, nullopt for values CiA 301 does not define.
std::optional<NmtState> nmt_state_from_byte(std::uint8_t value) noexcept;

struct NmtMessage {
  NmtCommand command = NmtCommand::start;
  std::uint8_t node_id = 0;  // 0 = every node
};

// NMT command frame: id 0x000, 2 bytes {command, node id}; node 0 addresses every node.
// Only the low 7 bits of node_id are sent (pass 0..127).
can_frame encode_nmt(NmtCommand command, std::uint8_t node_id) noexcept;
// nullopt unless id 0x000 data frame, length 2, a defined command, node 0..127.
std::optional<NmtMessage> decode_nmt(const can_frame& frame) noexcept;

// What an NMT frame did to the slave (at most one per frame).
enum class NmtEvent : std::uint8_t {
  none,                 // not for this node, not an NMT frame, or no change
  state_changed,        // start / stop / enter pre-operational changed the state
  reset_application,    // reset node: reset the application and communication areas
  reset_communication,  // reset communication: reset the communication area
};

// The slave's NMT state machine (CiA 301 Figure 48). Initialisation -> (boot-up message)
// -> pre-operational; start/stop/enter-pre-operational are accepted in every state
// after initialisation; both resets go back through initialisation, which the caller
// completes with boot() after resetting its object dictionary areas.
class NmtSlave {
 public:
  explicit NmtSlave(std::uint8_t node_id) noexcept : node_id_(node_id) {}

  // Ends initialisation: state pre-operational; returns the boot-up message to send.
  can_frame boot() noexcept;
  // Applies an NMT command addressed to this node (or to all); other frames are ignored.
  NmtEvent on_frame(const can_frame& frame) noexcept;
  // Applies a command directly (e.g. a local "NMT startup" setting).
  NmtEvent apply(NmtCommand command) noexcept;

  // `initialising` is true between construction / a reset and boot().
  bool initialising() const noexcept { return initialising_; }
  // The state as reported by the heartbeat (boot_up while initialising).
  NmtState state() const noexcept { return initialising_ ? NmtState::boot_up : state_; }
  std::uint8_t node_id() const noexcept { return node_id_; }

  // Which services CiA 301 Table 82 allows in the current state.
  bool sdo_allowed() const noexcept;   // pre-operational, operational
  bool pdo_allowed() const noexcept;   // operational
  bool sync_allowed() const noexcept;  // pre-operational, operational (SYNC and EMCY)
  bool emcy_allowed() const noexcept { return sync_allowed(); }

 private:
  std::uint8_t node_id_;
  bool initialising_ = true;
  NmtState state_ = NmtState::pre_operational;
};

}  // namespace trainer::hal::canopen
