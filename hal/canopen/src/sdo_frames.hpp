// SDO frame building and field access shared by the client and the server (CiA 301 v4.2,
// 7.2.4.3). Private to hal_canopen.
#pragma once

#include <linux/can.h>

#include <algorithm>
#include <cstdint>
#include <span>

#include "bytes.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::canopen::detail {

inline constexpr std::uint8_t kSdoFrameLength = 8;
inline constexpr std::size_t kSegmentDataBytes = 7;
inline constexpr std::size_t kExpeditedDataBytes = 4;
inline constexpr std::uint8_t kBitExpedited = 0x02;
inline constexpr std::uint8_t kBitSizeIndicated = 0x01;
inline constexpr std::uint8_t kBitToggle = 0x10;
inline constexpr std::uint8_t kBitLastSegment = 0x01;

inline std::uint16_t sdo_index(const can_frame& frame) noexcept { return get_u16(frame.data + 1); }
inline std::uint8_t sdo_sub(const can_frame& frame) noexcept { return frame.data[3]; }
inline std::uint8_t sdo_toggle(const can_frame& frame) noexcept {
  return static_cast<std::uint8_t>((frame.data[0] >> 4) & 1U);
}

inline can_frame sdo_frame(std::uint16_t cob_id) noexcept {
  can_frame frame{};
  frame.can_id = cob_id;
  frame.len = kSdoFrameLength;
  return frame;
}

// Command byte + multiplexer (index, sub), data bytes 4..7 zero.
inline can_frame sdo_initiate_frame(std::uint16_t cob_id, std::uint8_t command, std::uint16_t index,
                                    std::uint8_t sub) noexcept {
  can_frame frame = sdo_frame(cob_id);
  frame.data[0] = command;
  put_u16(frame.data + 1, index);
  frame.data[3] = sub;
  return frame;
}

inline can_frame sdo_abort_frame(std::uint16_t cob_id, std::uint16_t index, std::uint8_t sub,
                                 std::uint32_t code) noexcept {
  can_frame frame = sdo_initiate_frame(cob_id, static_cast<std::uint8_t>(kCsAbort << 5), index, sub);
  put_u32(frame.data + 4, code);
  return frame;
}

// Expedited initiate (download request or upload response) carrying 1..4 bytes, size
// indicated: specifier << 5 | n << 2 | e | s.
inline can_frame sdo_expedited_frame(std::uint16_t cob_id, std::uint8_t specifier, std::uint16_t index,
                                     std::uint8_t sub, std::span<const std::uint8_t> data) noexcept {
  const auto unused = static_cast<std::uint8_t>(kExpeditedDataBytes - data.size());
  can_frame frame = sdo_initiate_frame(
      cob_id, static_cast<std::uint8_t>((specifier << 5) | (unused << 2) | kBitExpedited | kBitSizeIndicated),
      index, sub);
  std::copy(data.begin(), data.end(), frame.data + 4);
  return frame;
}

// Segmented initiate with the size indicated in bytes 4..7: specifier << 5 | s.
inline can_frame sdo_segmented_initiate_frame(std::uint16_t cob_id, std::uint8_t specifier,
                                              std::uint16_t index, std::uint8_t sub,
                                              std::uint32_t size) noexcept {
  can_frame frame = sdo_initiate_frame(
      cob_id, static_cast<std::uint8_t>((specifier << 5) | kBitSizeIndicated), index, sub);
  put_u32(frame.data + 4, size);
  return frame;
}

// Segment with up to 7 bytes: specifier << 5 | t << 4 | n << 1 | c.
inline can_frame sdo_segment_frame(std::uint16_t cob_id, std::uint8_t specifier, std::uint8_t toggle,
                                   std::span<const std::uint8_t> data, bool last) noexcept {
  can_frame frame = sdo_frame(cob_id);
  const auto unused = static_cast<std::uint8_t>(kSegmentDataBytes - data.size());
  frame.data[0] = static_cast<std::uint8_t>((specifier << 5) | (toggle << 4) | (unused << 1) |
                                            (last ? kBitLastSegment : 0));
  std::copy(data.begin(), data.end(), frame.data + 1);
  return frame;
}

}  // namespace trainer::hal::canopen::detail
