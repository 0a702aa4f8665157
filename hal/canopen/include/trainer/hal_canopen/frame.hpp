// CANopen identifiers (CiA 301 v4.2, 7.3.5 "pre-defined connection set") and the
// classification of received classic CAN frames (Linux `struct can_frame`, 11-bit ids).
//
// Usage (master RT cycle, after read() from a SocketCAN socket):
//   const FrameClass c = classify(frame);
//   if (!c.ok()) { ++rejected; continue; }            // RTR, 29-bit id, wrong length, ...
//   switch (c.kind) {
//     case FrameKind::error_frame: decode_bus_error(frame) ...   (bus_error.hpp)
//     case FrameKind::heartbeat:   consumer.on_frame(frame, now_ns) ... (heartbeat.hpp)
//     case FrameKind::tpdo:        c.pdo_number (1..4), c.node_id ...  (pdo.hpp)
//     case FrameKind::sdo_response: sdo_client.on_frame(frame, now_ns) (sdo_client.hpp)
//     ...
//   }
// Builders: make_frame(cob_id, bytes); cob_id(Function, node) for the default COB-IDs.
//
// The library does no I/O: every type here is a value, every function noexcept and
// allocation-free. Node ids are 1..127 (kMinNodeId..kMaxNodeId); 0 addresses "all nodes"
// in NMT commands only.
#pragma once

#include <linux/can.h>

#include <cstddef>
#include <cstdint>
#include <span>

namespace trainer::hal::canopen {

inline constexpr std::uint8_t kMinNodeId = 1;
inline constexpr std::uint8_t kMaxNodeId = 127;
constexpr bool is_valid_node_id(unsigned node_id) noexcept {
  return node_id >= kMinNodeId && node_id <= kMaxNodeId;
}

// Base COB-IDs of the pre-defined connection set; the node id is added where the
// function is per node.
inline constexpr std::uint16_t kCobNmt = 0x000;
inline constexpr std::uint16_t kCobSync = 0x080;
inline constexpr std::uint16_t kCobEmcyBase = 0x080;
inline constexpr std::uint16_t kCobTime = 0x100;
inline constexpr std::uint16_t kCobTpdo1Base = 0x180;
inline constexpr std::uint16_t kCobRpdo1Base = 0x200;
inline constexpr std::uint16_t kCobTpdo2Base = 0x280;
inline constexpr std::uint16_t kCobRpdo2Base = 0x300;
inline constexpr std::uint16_t kCobTpdo3Base = 0x380;
inline constexpr std::uint16_t kCobRpdo3Base = 0x400;
inline constexpr std::uint16_t kCobTpdo4Base = 0x480;
inline constexpr std::uint16_t kCobRpdo4Base = 0x500;
inline constexpr std::uint16_t kCobSdoTxBase = 0x580;  // server -> client (responses)
inline constexpr std::uint16_t kCobSdoRxBase = 0x600;  // client -> server (requests)
inline constexpr std::uint16_t kCobHeartbeatBase = 0x700;  // heartbeat, boot-up (NMT error control)

enum class FrameKind : std::uint8_t {
  nmt,           // 0x000: NMT command (master -> slaves)
  sync,          // 0x080
  time,          // 0x100: TIME stamp (recognised, not decoded further)
  emcy,          // 0x080 + node
  tpdo,          // 0x180/0x280/0x380/0x480 + node (slave -> master), pdo_number 1..4
  rpdo,          // 0x200/0x300/0x400/0x500 + node (master -> slave), pdo_number 1..4
  sdo_response,  // 0x580 + node (server -> client)
  sdo_request,   // 0x600 + node (client -> server)
  heartbeat,     // 0x700 + node: heartbeat or boot-up
  error_frame,   // CAN_ERR_FLAG set: a SocketCAN error frame (bus_error.hpp)
  unknown,       // restricted or unassigned id (e.g. 0x001..0x07F, LSS 0x7E4/0x7E5)
};
const char* to_string(FrameKind kind) noexcept;

enum class FrameProblem : std::uint8_t {
  none,
  remote_request,  // RTR frame: RTR-PDOs and node guarding are not supported
  extended_id,     // 29-bit identifier (or id bits above bit 10 in a standard frame)
  bad_length,      // length the protocol forbids (NMT 2, SYNC 0/1, EMCY 8, SDO 8,
                   // heartbeat 1, TIME 6, error frame 8, anything > 8)
};
const char* to_string(FrameProblem problem) noexcept;

struct FrameClass {
  FrameKind kind = FrameKind::unknown;
  std::uint8_t node_id = 0;     // 1..127 for per-node functions, else 0
  std::uint8_t pdo_number = 0;  // 1..4 for tpdo/rpdo, else 0
  FrameProblem problem = FrameProblem::none;
  constexpr bool ok() const noexcept { return problem == FrameProblem::none; }
};

// Function, node and whether the frame is acceptable for that function. A frame with a
// problem still carries the kind and node its id names (so it can be counted per node),
// except extended-id frames, which are `unknown`.
FrameClass classify(const can_frame& frame) noexcept;

// The default COB-ID of a per-node function (pdo_number 1..4 for PDOs); 0 when node or
// pdo_number is out of range or the function is not per node.
std::uint16_t cob_id(FrameKind kind, std::uint8_t node_id, std::uint8_t pdo_number = 0) noexcept;

// A data frame with an 11-bit id and up to 8 bytes (longer input is cut at 8); every
// byte past `data.size()` and the padding fields are zero.
can_frame make_frame(std::uint16_t cob_id, std::span<const std::uint8_t> data) noexcept;

// The 11-bit identifier of a frame (flags stripped).
constexpr std::uint16_t frame_id(const can_frame& frame) noexcept {
  return static_cast<std::uint16_t>(frame.can_id & CAN_SFF_MASK);
}
constexpr bool is_remote(const can_frame& frame) noexcept {
  return (frame.can_id & CAN_RTR_FLAG) != 0;
}
constexpr bool is_extended(const can_frame& frame) noexcept {
  return (frame.can_id & CAN_EFF_FLAG) != 0;
}
constexpr bool is_error_frame(const can_frame& frame) noexcept {
  return (frame.can_id & CAN_ERR_FLAG) != 0;
}
// True for a plain data frame with this 11-bit id (no RTR/EFF/ERR flag).
constexpr bool is_data_frame_with_id(const can_frame& frame, std::uint16_t id) noexcept {
  return frame.can_id == static_cast<canid_t>(id);
}

}  // namespace trainer::hal::canopen
