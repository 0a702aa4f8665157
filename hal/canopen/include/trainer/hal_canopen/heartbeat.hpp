// Heartbeat and boot-up (CiA 301 v4.2, 7.2.8.3.2: id 0x700 + node, 1 byte = NMT state;
// the boot-up message is the same frame with state 0x00) and the heartbeat consumer
// (objects 0x1016 consumer heartbeat time, 0x1017 producer heartbeat time).
//
// Producer (slave): every 0x1017 ms: send(encode_heartbeat(node, nmt.state()));
// Consumer (master RT cycle):
//   HeartbeatConsumer hb;                          // setup
//   hb.add(node, 100);                             // or hb.add_entry(0x1016 sub value)
//   per received frame:  hb.on_frame(frame, now_ns);
//   once per cycle:      hb.on_time(now_ns);
//   while (auto e = hb.next_event()) {
//     e->event == HeartbeatEvent::timed_out  -> the node is lost (reported once)
//     e->event == HeartbeatEvent::boot_up    -> the node restarted: reconfigure it
//   }
//   hb.status(node)->health                      // not_seen / booted / alive / timed_out
//
// Monitoring of a node starts with its first heartbeat (CiA 301: "after the reception of
// the first heartbeat"). A boot-up message marks the node `booted` (seen, restarted,
// deadline not armed: after a reset its producer time is whatever its default is, and
// the master is expected to reconfigure it); the next heartbeat arms the deadline again.
// A node is timed out when no heartbeat arrived for longer than its consumer time; the
// state is latched until the node is heard again (event `recovered`). Consumer time 0
// disables monitoring of that entry (CiA 301).
#pragma once

#include <linux/can.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "trainer/core/status.hpp"
#include "trainer/hal_canopen/nmt.hpp"

namespace trainer::hal::canopen {

struct HeartbeatMessage {
  std::uint8_t node_id = 0;
  NmtState state = NmtState::boot_up;
};

can_frame encode_heartbeat(std::uint8_t node_id, NmtState state) noexcept;
// nullopt unless a data frame (no RTR: node guarding is not supported) with id
// 0x701..0x77F, length 1, and a defined state with bit 7 (the guarding toggle) clear.
std::optional<HeartbeatMessage> decode_heartbeat(const can_frame& frame) noexcept;

// Object 0x1016 sub-entry: bits 23..16 node id, 15..0 consumer time in ms.
constexpr std::uint32_t encode_consumer_entry(std::uint8_t node_id, std::uint16_t time_ms) noexcept {
  return (static_cast<std::uint32_t>(node_id) << 16) | time_ms;
}
struct ConsumerEntry {
  std::uint8_t node_id = 0;
  std::uint16_t time_ms = 0;
};
constexpr ConsumerEntry decode_consumer_entry(std::uint32_t value) noexcept {
  return {static_cast<std::uint8_t>((value >> 16) & 0xFFU), static_cast<std::uint16_t>(value & 0xFFFFU)};
}

enum class NodeHealth : std::uint8_t {
  not_seen,   // nothing received since add()
  booted,     // boot-up received; waiting for the first heartbeat (no deadline)
  alive,      // heartbeats within the consumer time
  timed_out,  // consumer time exceeded; latched until the node is heard again
};
const char* to_string(NodeHealth health) noexcept;

enum class HeartbeatEvent : std::uint8_t {
  timed_out,      // the deadline passed (once per loss)
  recovered,      // heard again after timed_out
  boot_up,        // boot-up message (state 0x00): the node restarted
  state_changed,  // the NMT state in the heartbeat differs from the previous one
};
const char* to_string(HeartbeatEvent event) noexcept;

struct HeartbeatEventRecord {
  std::uint8_t node_id = 0;
  HeartbeatEvent event = HeartbeatEvent::timed_out;
  std::optional<NmtState> state;  // the last state heard (nullopt: never heard)
};

struct NodeHeartbeatStatus {
  std::uint8_t node_id = 0;
  std::uint16_t consumer_time_ms = 0;
  NodeHealth health = NodeHealth::not_seen;
  std::optional<NmtState> state;  // last state heard
  std::int64_t last_heard_ns = 0;
  std::uint32_t boot_up_count = 0;
  std::uint32_t timeout_count = 0;
};

class HeartbeatConsumer {
 public:
  static constexpr std::size_t kCapacity = 32;

  // Setup: monitor `node_id` with `consumer_time_ms` (0 = entry disabled, node ignored).
  // invalid_argument for a node id outside 1..127 or already present; capacity_exceeded
  // beyond kCapacity.
  core::Status add(std::uint8_t node_id, std::uint16_t consumer_time_ms) noexcept;
  core::Status add_entry(std::uint32_t entry_0x1016) noexcept;
  void clear() noexcept { count_ = 0; }

  // True when the frame was the heartbeat / boot-up of a monitored node.
  bool on_frame(const can_frame& frame, std::int64_t now_ns) noexcept;
  // Checks every deadline; newly timed-out nodes get a timed_out event.
  void on_time(std::int64_t now_ns) noexcept;
  // Events not yet reported, one at a time (node order, then event order above).
  std::optional<HeartbeatEventRecord> next_event() noexcept;

  const NodeHeartbeatStatus* status(std::uint8_t node_id) const noexcept;
  std::size_t size() const noexcept { return count_; }
  bool all_alive() const noexcept;

 private:
  struct Node {
    NodeHeartbeatStatus status;
    std::uint8_t pending = 0;  // bit per HeartbeatEvent
  };
  Node* find(std::uint8_t node_id) noexcept;

  std::array<Node, kCapacity> nodes_{};
  std::size_t count_ = 0;
};

}  // namespace trainer::hal::canopen
