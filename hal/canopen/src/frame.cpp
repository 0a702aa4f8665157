// Classification of received frames by the pre-defined connection set (CiA 301 v4.2,
// Table 74: function code = id bits 10..7, node id = bits 6..0).
#include "trainer/hal_canopen/frame.hpp"

#include <algorithm>

namespace trainer::hal::canopen {

namespace {

// Function codes (id >> 7) of the pre-defined connection set.
constexpr unsigned kFunctionNmt = 0x0;
constexpr unsigned kFunctionSyncEmcy = 0x1;
constexpr unsigned kFunctionTime = 0x2;
constexpr unsigned kFunctionTpdo1 = 0x3;
constexpr unsigned kFunctionRpdo4 = 0xA;
constexpr unsigned kFunctionSdoTx = 0xB;
constexpr unsigned kFunctionSdoRx = 0xC;
constexpr unsigned kFunctionHeartbeat = 0xE;

constexpr std::uint8_t kNmtLength = 2;
constexpr std::uint8_t kTimeLength = 6;
constexpr std::uint8_t kEmcyLength = 8;
constexpr std::uint8_t kSdoLength = 8;
constexpr std::uint8_t kHeartbeatLength = 1;

FrameClass classify_by_id(std::uint16_t id) noexcept {
  const unsigned function = id >> 7;
  const auto node = static_cast<std::uint8_t>(id & 0x7FU);
  FrameClass result;
  if (node == 0) {
    if (function == kFunctionNmt) result.kind = FrameKind::nmt;
    if (function == kFunctionSyncEmcy) result.kind = FrameKind::sync;
    if (function == kFunctionTime) result.kind = FrameKind::time;
    return result;  // every other function with node 0 is restricted
  }
  if (function == kFunctionSyncEmcy) {
    result.kind = FrameKind::emcy;
  } else if (function >= kFunctionTpdo1 && function <= kFunctionRpdo4) {
    // 0x180 TPDO1, 0x200 RPDO1, 0x280 TPDO2, ... : odd offsets transmit, even receive.
    const unsigned offset = function - kFunctionTpdo1;
    result.kind = (offset % 2 == 0) ? FrameKind::tpdo : FrameKind::rpdo;
    result.pdo_number = static_cast<std::uint8_t>(offset / 2 + 1);
  } else if (function == kFunctionSdoTx) {
    result.kind = FrameKind::sdo_response;
  } else if (function == kFunctionSdoRx) {
    result.kind = FrameKind::sdo_request;
  } else if (function == kFunctionHeartbeat) {
    result.kind = FrameKind::heartbeat;
  } else {
    return result;  // 0x001..0x07F, 0x101..0x17F, 0x680..0x6FF, 0x780..0x7FF
  }
  result.node_id = node;
  return result;
}

bool length_allowed(FrameKind kind, std::uint8_t length) noexcept {
  switch (kind) {
    case FrameKind::nmt: return length == kNmtLength;
    case FrameKind::sync: return length <= 1;
    case FrameKind::time: return length == kTimeLength;
    case FrameKind::emcy: return length == kEmcyLength;
    case FrameKind::sdo_response:
    case FrameKind::sdo_request: return length == kSdoLength;
    case FrameKind::heartbeat: return length == kHeartbeatLength;
    case FrameKind::tpdo:
    case FrameKind::rpdo:
    case FrameKind::unknown: return length <= CAN_MAX_DLEN;
    case FrameKind::error_frame: return length == CAN_MAX_DLEN;
  }
  return false;
}

}  // namespace

FrameClass classify(const can_frame& frame) noexcept {
  FrameClass result;
  if (is_error_frame(frame)) {
    result.kind = FrameKind::error_frame;
    if (frame.len != CAN_MAX_DLEN) result.problem = FrameProblem::bad_length;
    return result;
  }
  // A 29-bit frame, or a standard frame with id bits above bit 10 (SocketCAN never delivers
  // one; a hand-made frame might).
  if (is_extended(frame) || (frame.can_id & CAN_EFF_MASK & ~CAN_SFF_MASK) != 0) {
    result.problem = FrameProblem::extended_id;
    return result;
  }
  result = classify_by_id(frame_id(frame));
  if (is_remote(frame)) {
    result.problem = FrameProblem::remote_request;
  } else if (!length_allowed(result.kind, frame.len)) {
    result.problem = FrameProblem::bad_length;
  }
  return result;
}

std::uint16_t cob_id(FrameKind kind, std::uint8_t node_id, std::uint8_t pdo_number) noexcept {
  if (!is_valid_node_id(node_id)) return 0;
  const bool pdo = kind == FrameKind::tpdo || kind == FrameKind::rpdo;
  if (pdo && (pdo_number < 1 || pdo_number > 4)) return 0;
  switch (kind) {
    case FrameKind::emcy: return static_cast<std::uint16_t>(kCobEmcyBase + node_id);
    case FrameKind::tpdo:
      return static_cast<std::uint16_t>(kCobTpdo1Base + 0x100U * (pdo_number - 1U) + node_id);
    case FrameKind::rpdo:
      return static_cast<std::uint16_t>(kCobRpdo1Base + 0x100U * (pdo_number - 1U) + node_id);
    case FrameKind::sdo_response: return static_cast<std::uint16_t>(kCobSdoTxBase + node_id);
    case FrameKind::sdo_request: return static_cast<std::uint16_t>(kCobSdoRxBase + node_id);
    case FrameKind::heartbeat: return static_cast<std::uint16_t>(kCobHeartbeatBase + node_id);
    default: return 0;
  }
}

can_frame make_frame(std::uint16_t cob_id, std::span<const std::uint8_t> data) noexcept {
  can_frame frame{};
  frame.can_id = static_cast<canid_t>(cob_id & CAN_SFF_MASK);
  const std::size_t length = std::min<std::size_t>(data.size(), CAN_MAX_DLEN);
  frame.len = static_cast<std::uint8_t>(length);
  std::copy_n(data.begin(), length, frame.data);
  return frame;
}

const char* to_string(FrameKind kind) noexcept {
  switch (kind) {
    case FrameKind::nmt: return "nmt";
    case FrameKind::sync: return "sync";
    case FrameKind::time: return "time";
    case FrameKind::emcy: return "emcy";
    case FrameKind::tpdo: return "tpdo";
    case FrameKind::rpdo: return "rpdo";
    case FrameKind::sdo_response: return "sdo_response";
    case FrameKind::sdo_request: return "sdo_request";
    case FrameKind::heartbeat: return "heartbeat";
    case FrameKind::error_frame: return "error_frame";
    case FrameKind::unknown: return "unknown";
  }
  return "?";
}

const char* to_string(FrameProblem problem) noexcept {
  switch (problem) {
    case FrameProblem::none: return "none";
    case FrameProblem::remote_request: return "remote request (RTR) not supported";
    case FrameProblem::extended_id: return "29-bit identifier not supported";
    case FrameProblem::bad_length: return "data length not allowed for this protocol";
  }
  return "?";
}

}  // namespace trainer::hal::canopen
