// Emergency objects (CiA 301 v4.2, 7.2.7: id 0x080 + node, 8 bytes: error code u16,
// error register u8 (object 0x1001), 5 manufacturer-specific bytes) and the texts of the
// emergency error codes of CiA 301 (Table 21) and CiA 402 / IEC 61800-7-201 (drives).
//
// Slave:  send(encode_emcy({node, 0x2310, kErrorRegisterGeneric | kErrorRegisterCurrent, {}}));
//         ...when the error is gone: send(encode_emcy({node, 0x0000, register_now, {}}));
// Master: if (auto e = decode_emcy(frame)) log(describe_emcy_code(e->error_code));
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace trainer::hal::canopen {

// Error register bits (object 0x1001).
inline constexpr std::uint8_t kErrorRegisterGeneric = 0x01;
inline constexpr std::uint8_t kErrorRegisterCurrent = 0x02;
inline constexpr std::uint8_t kErrorRegisterVoltage = 0x04;
inline constexpr std::uint8_t kErrorRegisterTemperature = 0x08;
inline constexpr std::uint8_t kErrorRegisterCommunication = 0x10;
inline constexpr std::uint8_t kErrorRegisterDeviceProfile = 0x20;
inline constexpr std::uint8_t kErrorRegisterReserved = 0x40;  // always 0
inline constexpr std::uint8_t kErrorRegisterManufacturer = 0x80;

// A few emergency codes the library itself refers to.
inline constexpr std::uint16_t kEmcyNoError = 0x0000;
inline constexpr std::uint16_t kEmcyGeneric = 0x1000;
inline constexpr std::uint16_t kEmcyCanOverrun = 0x8110;
inline constexpr std::uint16_t kEmcyCanErrorPassive = 0x8120;
inline constexpr std::uint16_t kEmcyHeartbeatError = 0x8130;
inline constexpr std::uint16_t kEmcyRecoveredFromBusOff = 0x8140;
inline constexpr std::uint16_t kEmcyPdoLengthError = 0x8210;
inline constexpr std::uint16_t kEmcyPdoLengthExceeded = 0x8220;
inline constexpr std::uint16_t kEmcyUnexpectedSyncLength = 0x8240;
inline constexpr std::uint16_t kEmcyRpdoTimeout = 0x8250;

struct EmcyMessage {
  std::uint8_t node_id = 0;
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer_data{};
};

can_frame encode_emcy(const EmcyMessage& message) noexcept;
// nullopt unless a data frame with id 0x081..0x0FF and length 8 (CiA 301 fixes 8).
std::optional<EmcyMessage> decode_emcy(const can_frame& frame) noexcept;

// Text of an emergency error code: the CiA 301 / CiA 402 entry when the code has one,
// else the text of its class (high byte, then high nibble), e.g. 0x2311 -> "continuous
// over-current (device output side)"; 0x23AB -> "current, device output side".
// 0xFFxx: "device specific (manufacturer)". Never null.
const char* describe_emcy_code(std::uint16_t error_code) noexcept;
// The class text alone (from the high byte / nibble).
const char* describe_emcy_class(std::uint16_t error_code) noexcept;

// "generic, current, temperature" (or "no error") into `buffer`, NUL-terminated.
std::string_view format_error_register(std::uint8_t error_register, std::span<char> buffer) noexcept;

}  // namespace trainer::hal::canopen
