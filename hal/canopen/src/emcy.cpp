// Emergency codec and the error code texts: CiA 301 v4.2 Table 21 (classes and the
// communication codes) and the drive codes of CiA 402-2 / IEC 61800-7-201 Annex.
#include "trainer/hal_canopen/emcy.hpp"

#include <algorithm>
#include <cstddef>

#include "bytes.hpp"
#include "trainer/hal_canopen/frame.hpp"

namespace trainer::hal::canopen {

namespace {

struct EmcyText {
  std::uint16_t code;
  const char* text;
};

// Specific codes, sorted by code (binary search).
constexpr EmcyText kEmcyCodes[] = {
    {0x0000, "error reset or no error"},
    {0x1000, "generic error"},
    {0x2110, "short circuit/earth leakage (device input side)"},
    {0x2120, "earth leakage (device input side)"},
    {0x2130, "short circuit (device input side)"},
    {0x2211, "internal current no. 1"},
    {0x2212, "internal current no. 2"},
    {0x2213, "over-current in ramp function"},
    {0x2214, "over-current in the sequence"},
    {0x2220, "continuous over-current (device internal)"},
    {0x2230, "short circuit/earth leakage (device internal)"},
    {0x2240, "earth leakage (device internal)"},
    {0x2250, "short circuit (device internal)"},
    {0x2310, "continuous over-current (device output side)"},
    {0x2320, "short circuit/earth leakage (motor side)"},
    {0x2330, "earth leakage (motor side)"},
    {0x2340, "short circuit (motor side)"},
    {0x3110, "mains over-voltage"},
    {0x3120, "mains under-voltage"},
    {0x3130, "mains phase failure"},
    {0x3140, "mains frequency"},
    {0x3210, "DC link over-voltage"},
    {0x3220, "DC link under-voltage"},
    {0x3230, "load error"},
    {0x3310, "output over-voltage"},
    {0x3320, "armature circuit"},
    {0x3330, "field circuit"},
    {0x4110, "excess ambient temperature"},
    {0x4120, "too low ambient temperature"},
    {0x4130, "supply air temperature"},
    {0x4140, "air outlet temperature"},
    {0x4210, "excess temperature device"},
    {0x4220, "too low temperature device"},
    {0x4300, "drive temperature"},
    {0x4310, "excess temperature drive"},
    {0x4320, "too low temperature drive"},
    {0x4400, "supply temperature"},
    {0x4410, "excess temperature supply"},
    {0x4420, "too low temperature supply"},
    {0x5100, "supply"},
    {0x5110, "supply low voltage"},
    {0x5111, "supply low voltage U1 (+/-15 V)"},
    {0x5112, "supply low voltage U2 (+24 V)"},
    {0x5113, "supply low voltage U3 (+5 V)"},
    {0x5120, "supply intermediate circuit"},
    {0x5200, "control"},
    {0x5210, "control measurement circuit"},
    {0x5220, "control computing circuit"},
    {0x5300, "operating unit"},
    {0x5400, "power section"},
    {0x5410, "output stages"},
    {0x5420, "chopper"},
    {0x5430, "input stages"},
    {0x5440, "contacts"},
    {0x5450, "fuses"},
    {0x5500, "data storage"},
    {0x5510, "working memory (RAM)"},
    {0x5520, "program memory"},
    {0x5530, "non-volatile data memory (EEPROM)"},
    {0x6010, "software reset (watchdog)"},
    {0x6310, "loss of parameters"},
    {0x6320, "parameter error"},
    {0x7100, "power"},
    {0x7110, "brake chopper"},
    {0x7111, "brake chopper failure"},
    {0x7112, "brake chopper over-current"},
    {0x7113, "brake chopper protective circuit"},
    {0x7120, "motor"},
    {0x7121, "motor blocked"},
    {0x7122, "motor error or commutation malfunction"},
    {0x7123, "motor tilted"},
    {0x7200, "measurement circuit"},
    {0x7300, "sensor"},
    {0x7301, "tacho fault"},
    {0x7302, "tacho wrong polarity"},
    {0x7303, "resolver 1 fault"},
    {0x7304, "resolver 2 fault"},
    {0x7305, "incremental sensor 1 fault"},
    {0x7306, "incremental sensor 2 fault"},
    {0x7307, "incremental sensor 3 fault"},
    {0x7310, "speed"},
    {0x7320, "position"},
    {0x7400, "computation circuit"},
    {0x7500, "communication"},
    {0x7510, "serial interface no. 1"},
    {0x7520, "serial interface no. 2"},
    {0x7600, "data storage (external)"},
    {0x8110, "CAN overrun (objects lost)"},
    {0x8120, "CAN in error passive mode"},
    {0x8130, "life guard error or heartbeat error"},
    {0x8140, "recovered from bus-off"},
    {0x8150, "CAN-ID collision"},
    {0x8210, "PDO not processed due to length error"},
    {0x8220, "PDO length exceeded"},
    {0x8230, "DAM MPDO not processed, destination object not available"},
    {0x8240, "unexpected SYNC data length"},
    {0x8250, "RPDO timeout"},
    {0x8300, "torque control"},
    {0x8311, "excess torque"},
    {0x8312, "difficult start up"},
    {0x8313, "standstill torque"},
    {0x8321, "insufficient torque"},
    {0x8331, "torque fault"},
    {0x8400, "velocity speed controller"},
    {0x8500, "position controller"},
    {0x8600, "positioning controller"},
    {0x8611, "following error"},
    {0x8612, "reference limit"},
    {0x8700, "sync controller"},
    {0x8800, "winding controller"},
    {0x9000, "external error"},
    {0xF001, "deceleration"},
    {0xF002, "sub-synchronous run"},
    {0xF003, "stroke operation"},
    {0xF004, "control"},
};

// Classes by high byte (CiA 301 Table 21), sorted.
constexpr EmcyText kEmcyByteClasses[] = {
    {0x0000, "error reset or no error"},
    {0x1000, "generic error"},
    {0x2000, "current"},
    {0x2100, "current, device input side"},
    {0x2200, "current inside the device"},
    {0x2300, "current, device output side"},
    {0x3000, "voltage"},
    {0x3100, "mains voltage"},
    {0x3200, "voltage inside the device"},
    {0x3300, "output voltage"},
    {0x4000, "temperature"},
    {0x4100, "ambient temperature"},
    {0x4200, "device temperature"},
    {0x5000, "device hardware"},
    {0x6000, "device software"},
    {0x6100, "internal software"},
    {0x6200, "user software"},
    {0x6300, "data set"},
    {0x7000, "additional modules"},
    {0x8000, "monitoring"},
    {0x8100, "communication"},
    {0x8200, "protocol error"},
    {0x9000, "external error"},
    {0xF000, "additional functions"},
    {0xFF00, "device specific (manufacturer)"},
};

const char* find_text(std::span<const EmcyText> table, std::uint16_t code) noexcept {
  const auto it = std::lower_bound(table.begin(), table.end(), code,
                                    [](const EmcyText& entry, std::uint16_t value) {
                                      return entry.code < value;
                                    });
  return (it != table.end() && it->code == code) ? it->text : nullptr;
}

constexpr std::array<const char*, 8> kErrorRegisterNames = {
    "generic", "current", "voltage", "temperature", "communication", "device profile",
    "reserved bit 6", "manufacturer"};

}  // namespace

can_frame encode_emcy(const EmcyMessage& message) noexcept {
  std::uint8_t data[8] = {};
  detail::put_u16(data, message.error_code);
  data[2] = message.error_register;
  std::copy(message.manufacturer_data.begin(), message.manufacturer_data.end(), data + 3);
  return make_frame(static_cast<std::uint16_t>(kCobEmcyBase + (message.node_id & 0x7FU)), data);
}

std::optional<EmcyMessage> decode_emcy(const can_frame& frame) noexcept {
  if ((frame.can_id & ~CAN_SFF_MASK) != 0 || frame.len != 8) {  // flags or id bits above 10
    return std::nullopt;
  }
  const std::uint16_t id = frame_id(frame);
  if (id <= kCobEmcyBase || id > kCobEmcyBase + kMaxNodeId) return std::nullopt;
  EmcyMessage message;
  message.node_id = static_cast<std::uint8_t>(id - kCobEmcyBase);
  message.error_code = detail::get_u16(frame.data);
  message.error_register = frame.data[2];
  std::copy_n(frame.data + 3, 5, message.manufacturer_data.begin());
  return message;
}

const char* describe_emcy_class(std::uint16_t error_code) noexcept {
  if (const char* text = find_text(kEmcyByteClasses, static_cast<std::uint16_t>(error_code & 0xFF00U))) {
    return text;
  }
  if (const char* text = find_text(kEmcyByteClasses, static_cast<std::uint16_t>(error_code & 0xF000U))) {
    return text;
  }
  return "unassigned error code class";
}

const char* describe_emcy_code(std::uint16_t error_code) noexcept {
  if (const char* text = find_text(kEmcyCodes, error_code)) return text;
  // Numbered variants (0x2311 "no. 1" of 0x2310, 0x8251 RPDO 1 of 0x8250, ...): the
  // entry of their group of 16, except in the manufacturer range.
  if ((error_code & 0xFF00U) != 0xFF00U) {
    if (const char* text = find_text(kEmcyCodes, static_cast<std::uint16_t>(error_code & 0xFFF0U))) {
      return text;
    }
  }
  return describe_emcy_class(error_code);
}

std::string_view format_error_register(std::uint8_t error_register, std::span<char> buffer) noexcept {
  if (buffer.empty()) return {};
  std::size_t length = 0;
  auto append = [&](std::string_view text) {
    const std::size_t count = std::min(text.size(), buffer.size() - 1 - length);
    std::copy_n(text.data(), count, buffer.data() + length);
    length += count;
  };
  if (error_register == 0) append("no error");
  for (std::size_t bit = 0; bit < kErrorRegisterNames.size(); ++bit) {
    if ((error_register & (1U << bit)) == 0) continue;
    if (length > 0) append(", ");
    append(kErrorRegisterNames[bit]);
  }
  buffer[length] = '\0';
  return {buffer.data(), length};
}

}  // namespace trainer::hal::canopen
