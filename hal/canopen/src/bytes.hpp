// Little-endian field access in frame data (CANopen transmits every numeric type
// little-endian, CiA 301 7.1.5). Private to hal_canopen.
#pragma once

#include <cstddef>
#include <cstdint>

namespace trainer::hal::canopen::detail {

inline std::uint16_t get_u16(const std::uint8_t* data) noexcept {
  return static_cast<std::uint16_t>(data[0] | (data[1] << 8));
}
inline std::uint32_t get_u32(const std::uint8_t* data) noexcept {
  return static_cast<std::uint32_t>(data[0]) | (static_cast<std::uint32_t>(data[1]) << 8) |
         (static_cast<std::uint32_t>(data[2]) << 16) | (static_cast<std::uint32_t>(data[3]) << 24);
}
inline void put_u16(std::uint8_t* data, std::uint16_t value) noexcept {
  data[0] = static_cast<std::uint8_t>(value & 0xFFU);
  data[1] = static_cast<std::uint8_t>(value >> 8);
}
inline void put_u32(std::uint8_t* data, std::uint32_t value) noexcept {
  for (std::size_t i = 0; i < 4; ++i) data[i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU);
}
// `count` bytes (<= 8) as an unsigned little-endian number.
inline std::uint64_t get_le(const std::uint8_t* data, std::size_t count) noexcept {
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < count; ++i) value |= static_cast<std::uint64_t>(data[i]) << (8 * i);
  return value;
}
inline void put_le(std::uint8_t* data, std::size_t count, std::uint64_t value) noexcept {
  for (std::size_t i = 0; i < count; ++i) data[i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU);
}

}  // namespace trainer::hal::canopen::detail
