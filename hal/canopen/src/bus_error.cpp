// SocketCAN error frame decoding (linux/can/error.h: class bits in can_id, details in data).
#include "trainer/hal_canopen/bus_error.hpp"

#include <linux/can/error.h>

#include <algorithm>
#include <cstddef>
#include <utility>

namespace trainer::hal::canopen {

namespace {

constexpr std::uint8_t kErrorWarningCount = CAN_ERROR_WARNING_THRESHOLD;  // 96
constexpr std::uint8_t kErrorPassiveCount = 128;  // CAN_ERROR_PASSIVE_THRESHOLD

// Appends NUL-terminated text to a fixed buffer, cutting at the end.
class TextAppender {
 public:
  explicit TextAppender(std::span<char> buffer) noexcept : buffer_(buffer) {
    if (!buffer_.empty()) buffer_[0] = '\0';
  }
  void append(std::string_view text) noexcept {
    if (buffer_.empty()) return;
    const std::size_t room = buffer_.size() - 1 - length_;
    const std::size_t count = std::min(room, text.size());
    std::copy_n(text.data(), count, buffer_.data() + length_);
    length_ += count;
    buffer_[length_] = '\0';
  }
  void append_number(unsigned value) noexcept {
    char digits[12];
    std::size_t count = 0;
    do {
      digits[count++] = static_cast<char>('0' + value % 10);
      value /= 10;
    } while (value != 0 && count < sizeof(digits));
    std::reverse(digits, digits + count);
    append(std::string_view(digits, count));
  }
  // Starts a new item: "; " between groups.
  void group(std::string_view text) noexcept {
    if (length_ > 0) append("; ");
    append(text);
  }
  std::string_view view() const noexcept { return {buffer_.data(), length_}; }

 private:
  std::span<char> buffer_;
  std::size_t length_ = 0;
};

void append_bits(TextAppender& text, std::uint8_t bits,
                 std::span<const std::pair<std::uint8_t, const char*>> names) noexcept {
  bool first = true;
  for (const auto& [bit, name] : names) {
    if ((bits & bit) == 0) continue;
    text.append(first ? " " : ", ");
    text.append(name);
    first = false;
  }
  if (first) text.append(" unspecified");
}

constexpr std::pair<std::uint8_t, const char*> kControllerBits[] = {
    {CAN_ERR_CRTL_RX_OVERFLOW, "rx buffer overflow"}, {CAN_ERR_CRTL_TX_OVERFLOW, "tx buffer overflow"},
    {CAN_ERR_CRTL_RX_WARNING, "rx warning"},          {CAN_ERR_CRTL_TX_WARNING, "tx warning"},
    {CAN_ERR_CRTL_RX_PASSIVE, "rx error passive"},    {CAN_ERR_CRTL_TX_PASSIVE, "tx error passive"},
    {CAN_ERR_CRTL_ACTIVE, "back to error active"},
};
constexpr std::pair<std::uint8_t, const char*> kProtocolBits[] = {
    {CAN_ERR_PROT_BIT, "bit error"},
    {CAN_ERR_PROT_FORM, "form error"},
    {CAN_ERR_PROT_STUFF, "stuff error"},
    {CAN_ERR_PROT_BIT0, "cannot send dominant bit"},
    {CAN_ERR_PROT_BIT1, "cannot send recessive bit"},
    {CAN_ERR_PROT_OVERLOAD, "bus overload"},
    {CAN_ERR_PROT_ACTIVE, "active error announcement"},
    {CAN_ERR_PROT_TX, "on transmission"},
};

const char* describe_transceiver(std::uint8_t status) noexcept {
  switch (status) {
    case CAN_ERR_TRX_UNSPEC: return "unspecified";
    case CAN_ERR_TRX_CANH_NO_WIRE: return "CAN_H no wire";
    case CAN_ERR_TRX_CANH_SHORT_TO_BAT: return "CAN_H short to battery";
    case CAN_ERR_TRX_CANH_SHORT_TO_VCC: return "CAN_H short to VCC";
    case CAN_ERR_TRX_CANH_SHORT_TO_GND: return "CAN_H short to ground";
    case CAN_ERR_TRX_CANL_NO_WIRE: return "CAN_L no wire";
    case CAN_ERR_TRX_CANL_SHORT_TO_BAT: return "CAN_L short to battery";
    case CAN_ERR_TRX_CANL_SHORT_TO_VCC: return "CAN_L short to VCC";
    case CAN_ERR_TRX_CANL_SHORT_TO_GND: return "CAN_L short to ground";
    case CAN_ERR_TRX_CANL_SHORT_TO_CANH: return "CAN_L short to CAN_H";
    default: return "other";
  }
}

BusSeverity severity_of(const BusError& error) noexcept {
  if (error.bus_off) return BusSeverity::bus_off;
  const std::uint8_t passive = CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE;
  const bool counters_passive = error.counters_valid && (error.tx_error_count >= kErrorPassiveCount ||
                                                         error.rx_error_count >= kErrorPassiveCount);
  if ((error.controller && (error.controller_status & passive) != 0) || counters_passive) {
    return BusSeverity::error_passive;
  }
  const std::uint8_t warning_bits = CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING |
                                    CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW;
  const bool counters_warning = error.counters_valid && (error.tx_error_count >= kErrorWarningCount ||
                                                         error.rx_error_count >= kErrorWarningCount);
  if ((error.controller && (error.controller_status & warning_bits) != 0) || counters_warning ||
      error.tx_timeout || error.lost_arbitration || error.protocol || error.transceiver ||
      error.no_ack || error.bus_error) {
    return BusSeverity::warning;
  }
  return BusSeverity::info;
}

}  // namespace

std::optional<BusError> decode_bus_error(const can_frame& frame) noexcept {
  if ((frame.can_id & CAN_ERR_FLAG) == 0 || frame.len != CAN_ERR_DLC) return std::nullopt;
  BusError error;
  error.classes = frame.can_id & CAN_ERR_MASK;
  error.tx_timeout = (error.classes & CAN_ERR_TX_TIMEOUT) != 0;
  error.lost_arbitration = (error.classes & CAN_ERR_LOSTARB) != 0;
  error.controller = (error.classes & CAN_ERR_CRTL) != 0;
  error.protocol = (error.classes & CAN_ERR_PROT) != 0;
  error.transceiver = (error.classes & CAN_ERR_TRX) != 0;
  error.no_ack = (error.classes & CAN_ERR_ACK) != 0;
  error.bus_off = (error.classes & CAN_ERR_BUSOFF) != 0;
  error.bus_error = (error.classes & CAN_ERR_BUSERROR) != 0;
  error.restarted = (error.classes & CAN_ERR_RESTARTED) != 0;
  error.counters_valid = (error.classes & CAN_ERR_CNT) != 0;
  error.arbitration_bit = frame.data[0];
  error.controller_status = frame.data[1];
  error.protocol_type = frame.data[2];
  error.protocol_location = frame.data[3];
  error.transceiver_status = frame.data[4];
  error.tx_error_count = frame.data[6];
  error.rx_error_count = frame.data[7];
  error.severity = severity_of(error);
  return error;
}

std::string_view format_bus_error(const BusError& error, std::span<char> buffer) noexcept {
  TextAppender text(buffer);
  if (error.bus_off) text.group("bus-off");
  if (error.restarted) text.group("controller restarted");
  if (error.controller) {
    text.group("controller:");
    append_bits(text, error.controller_status, kControllerBits);
  }
  if (error.protocol) {
    text.group("protocol violation:");
    append_bits(text, error.protocol_type, kProtocolBits);
    text.append(" at ");
    text.append(describe_protocol_location(error.protocol_location));
  }
  if (error.no_ack) text.group("no ACK on transmission");
  if (error.lost_arbitration) {
    text.group("lost arbitration at bit ");
    text.append_number(error.arbitration_bit);
  }
  if (error.tx_timeout) text.group("tx timeout");
  if (error.transceiver) {
    text.group("transceiver: ");
    text.append(describe_transceiver(error.transceiver_status));
  }
  if (error.bus_error) text.group("bus error");
  if (error.counters_valid) {
    text.group("tx/rx error counters ");
    text.append_number(error.tx_error_count);
    text.append("/");
    text.append_number(error.rx_error_count);
  }
  if (text.view().empty()) text.append("error frame without class bits");
  return text.view();
}

const char* describe_protocol_location(std::uint8_t location) noexcept {
  switch (location) {
    case CAN_ERR_PROT_LOC_UNSPEC: return "unspecified location";
    case CAN_ERR_PROT_LOC_SOF: return "start of frame";
    case CAN_ERR_PROT_LOC_ID28_21: return "id bits 28-21 (SFF 10-3)";
    case CAN_ERR_PROT_LOC_ID20_18: return "id bits 20-18 (SFF 2-0)";
    case CAN_ERR_PROT_LOC_SRTR: return "substitute RTR (SFF RTR)";
    case CAN_ERR_PROT_LOC_IDE: return "identifier extension";
    case CAN_ERR_PROT_LOC_ID17_13: return "id bits 17-13";
    case CAN_ERR_PROT_LOC_ID12_05: return "id bits 12-5";
    case CAN_ERR_PROT_LOC_ID04_00: return "id bits 4-0";
    case CAN_ERR_PROT_LOC_RTR: return "RTR";
    case CAN_ERR_PROT_LOC_RES1: return "reserved bit 1";
    case CAN_ERR_PROT_LOC_RES0: return "reserved bit 0";
    case CAN_ERR_PROT_LOC_DLC: return "data length code";
    case CAN_ERR_PROT_LOC_DATA: return "data section";
    case CAN_ERR_PROT_LOC_CRC_SEQ: return "CRC sequence";
    case CAN_ERR_PROT_LOC_CRC_DEL: return "CRC delimiter";
    case CAN_ERR_PROT_LOC_ACK: return "ACK slot";
    case CAN_ERR_PROT_LOC_ACK_DEL: return "ACK delimiter";
    case CAN_ERR_PROT_LOC_EOF: return "end of frame";
    case CAN_ERR_PROT_LOC_INTERM: return "intermission";
    default: return "unknown location";
  }
}

const char* to_string(BusSeverity severity) noexcept {
  switch (severity) {
    case BusSeverity::info: return "info";
    case BusSeverity::warning: return "warning";
    case BusSeverity::error_passive: return "error passive";
    case BusSeverity::bus_off: return "bus-off";
  }
  return "?";
}

}  // namespace trainer::hal::canopen
