// SocketCAN error frames (CAN_ERR_FLAG, <linux/can/error.h>) decoded into a small struct
// and a one-line text. Error frames arrive only when the socket asked for them
// (setsockopt CAN_RAW_ERR_FILTER); classify() reports them as FrameKind::error_frame.
//
// Usage:
//   if (const auto error = decode_bus_error(frame)) {
//     if (error->bus_off) { ...latch a fault, the controller has left the bus... }
//     char text[160];
//     log(format_bus_error(*error, text));   // "bus-off; controller: tx error passive"
//   }
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace trainer::hal::canopen {

// How bad the state this error frame reports is, worst first wins.
enum class BusSeverity : std::uint8_t {
  info,           // recovered to error active, restarted, counters only
  warning,        // error warning level, lost arbitration, single protocol errors, overflow
  error_passive,  // the controller no longer sends active error flags
  bus_off,        // the controller has left the bus; nothing is sent until a restart
};
const char* to_string(BusSeverity severity) noexcept;

struct BusError {
  std::uint32_t classes = 0;  // the CAN_ERR_* class bits of can_id (CAN_ERR_MASK)
  bool tx_timeout = false;        // CAN_ERR_TX_TIMEOUT
  bool lost_arbitration = false;  // CAN_ERR_LOSTARB; bit in arbitration_bit
  bool controller = false;        // CAN_ERR_CRTL; details in controller_status
  bool protocol = false;          // CAN_ERR_PROT; protocol_type, protocol_location
  bool transceiver = false;       // CAN_ERR_TRX; transceiver_status
  bool no_ack = false;            // CAN_ERR_ACK: nobody acknowledged our frame
  bool bus_off = false;           // CAN_ERR_BUSOFF
  bool bus_error = false;         // CAN_ERR_BUSERROR
  bool restarted = false;         // CAN_ERR_RESTARTED: controller restarted after bus-off
  bool counters_valid = false;    // CAN_ERR_CNT: tx/rx error counters in data[6], data[7]
  std::uint8_t arbitration_bit = 0;     // data[0]
  std::uint8_t controller_status = 0;   // data[1]: CAN_ERR_CRTL_* bits
  std::uint8_t protocol_type = 0;       // data[2]: CAN_ERR_PROT_* bits
  std::uint8_t protocol_location = 0;   // data[3]: CAN_ERR_PROT_LOC_*
  std::uint8_t transceiver_status = 0;  // data[4]: CAN_ERR_TRX_*
  std::uint8_t tx_error_count = 0;      // data[6]
  std::uint8_t rx_error_count = 0;      // data[7]
  BusSeverity severity = BusSeverity::info;
};

// nullopt when the frame is not an error frame or its length is not CAN_ERR_DLC (8).
std::optional<BusError> decode_bus_error(const can_frame& frame) noexcept;

// Text of the error, e.g. "bus-off; controller: rx error passive, tx warning;
// tx/rx error counters 128/0", written into `buffer` (always NUL-terminated, cut when
// full). Returns the written part.
std::string_view format_bus_error(const BusError& error, std::span<char> buffer) noexcept;

// Text of one CAN_ERR_PROT_LOC_* value ("ACK slot", "data section", ...).
const char* describe_protocol_location(std::uint8_t location) noexcept;

}  // namespace trainer::hal::canopen
