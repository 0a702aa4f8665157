// Byte layouts of docs/usb-protocol.md ("Reports"), written and read field by field,
// little-endian.
#include "trainer/hal_usbproto/protocol.hpp"

#include <algorithm>

namespace trainer::hal::usbproto {
namespace {

// Offsets in the IN report.
constexpr std::size_t kInChannelCountAt = 2;
constexpr std::size_t kInSequenceAt = 3;
constexpr std::size_t kInOutSequenceAt = 5;
constexpr std::size_t kInTimeAt = 7;
constexpr std::size_t kInStatusAt = 11;
constexpr std::size_t kInButtonsAt = 13;
constexpr std::size_t kInCountsAt = 15;
constexpr std::size_t kWireCountBytes = 3;
static_assert(kInCountsAt + kMaxChannels * kWireCountBytes == kReportSize - 1);

// Offsets in the OUT report.
constexpr std::size_t kOutChannelCountAt = 2;
constexpr std::size_t kOutFlagsAt = 3;
constexpr std::size_t kOutSequenceAt = 4;
constexpr std::size_t kOutCurrentsAt = 6;
constexpr std::size_t kOutReservedAt = kOutCurrentsAt + 2 * kMaxChannels;  // .. 62
static_assert(kOutReservedAt < kReportSize - 1);

// Offsets in the identity.
constexpr std::size_t kIdChannelCountAt = 2;
constexpr std::size_t kIdReservedAt = 3;
constexpr std::size_t kIdFirmwareAt = 4;
constexpr std::size_t kIdWatchdogAt = 6;
constexpr std::size_t kIdFrameIntervalAt = 8;
constexpr std::size_t kIdMaxCurrentAt = 12;
constexpr std::size_t kIdReserved2At = 14;

constexpr std::size_t kVersionAt = 1;

std::uint16_t usb_get_u16(const std::uint8_t* data) noexcept {
  return static_cast<std::uint16_t>(data[0] | (data[1] << 8));
}
std::uint32_t usb_get_u32(const std::uint8_t* data) noexcept {
  return static_cast<std::uint32_t>(data[0]) | (static_cast<std::uint32_t>(data[1]) << 8) |
         (static_cast<std::uint32_t>(data[2]) << 16) | (static_cast<std::uint32_t>(data[3]) << 24);
}
void usb_put_u16(std::uint8_t* data, std::uint16_t value) noexcept {
  data[0] = static_cast<std::uint8_t>(value & 0xFFU);
  data[1] = static_cast<std::uint8_t>(value >> 8);
}
void usb_put_u32(std::uint8_t* data, std::uint32_t value) noexcept {
  for (std::size_t i = 0; i < 4; ++i) data[i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU);
}
// Signed 24-bit little-endian.
std::int32_t usb_get_i24(const std::uint8_t* data) noexcept {
  const std::uint32_t low = static_cast<std::uint32_t>(data[0]) |
                            (static_cast<std::uint32_t>(data[1]) << 8) |
                            (static_cast<std::uint32_t>(data[2]) << 16);
  return low >= 0x800000U ? static_cast<std::int32_t>(low) - (1 << 24) : static_cast<std::int32_t>(low);
}
void usb_put_i24(std::uint8_t* data, std::int32_t value) noexcept {
  const auto bits = static_cast<std::uint32_t>(value);
  for (std::size_t i = 0; i < 3; ++i) data[i] = static_cast<std::uint8_t>((bits >> (8 * i)) & 0xFFU);
}

bool usb_all_zero(std::span<const std::uint8_t> bytes) noexcept {
  return std::all_of(bytes.begin(), bytes.end(), [](std::uint8_t b) { return b == 0; });
}

// The checks every decoder makes in the same order: length, magic, version, CRC.
DecodeStatus usb_check_envelope(std::span<const std::uint8_t> bytes, std::size_t size,
                                std::uint8_t magic) noexcept {
  if (bytes.size() != size) return DecodeStatus::wrong_length;
  if (bytes[0] != magic) return DecodeStatus::bad_magic;
  if (bytes[kVersionAt] != kProtocolVersion) return DecodeStatus::bad_version;
  if (crc8(bytes.first(size - 1)) != bytes[size - 1]) return DecodeStatus::bad_checksum;
  return DecodeStatus::ok;
}

}  // namespace

const char* to_string(DecodeStatus status) noexcept {
  switch (status) {
    case DecodeStatus::ok: return "ok";
    case DecodeStatus::wrong_length: return "wrong length";
    case DecodeStatus::bad_magic: return "bad magic byte";
    case DecodeStatus::bad_version: return "unsupported protocol version";
    case DecodeStatus::bad_checksum: return "CRC-8 mismatch";
    case DecodeStatus::bad_channel_count: return "channel count above 16";
    case DecodeStatus::reserved_not_zero: return "reserved byte, flag or unused channel not zero";
  }
  return "?";
}

std::uint8_t crc8(std::span<const std::uint8_t> bytes) noexcept {
  std::uint8_t crc = 0;
  for (const std::uint8_t byte : bytes) {
    crc = static_cast<std::uint8_t>(crc ^ byte);
    for (int bit = 0; bit < 8; ++bit) {
      const unsigned shifted = static_cast<unsigned>(crc) << 1U;
      crc = static_cast<std::uint8_t>((crc & 0x80U) != 0 ? (shifted ^ 0x07U) : shifted);
    }
  }
  return crc;
}

// --- IN ------------------------------------------------------------------------------------

std::size_t encode(const InReport& report, std::span<std::uint8_t, kReportSize> bytes) noexcept {
  if (report.channel_count > kMaxChannels) return 0;
  for (std::size_t i = 0; i < kMaxChannels; ++i) {
    const std::int32_t count = report.counts[i];
    if (i >= report.channel_count && count != 0) return 0;
    if (count < kMinWireCount || count > kMaxWireCount) return 0;
  }
  std::fill(bytes.begin(), bytes.end(), std::uint8_t{0});
  std::uint8_t* data = bytes.data();
  data[0] = kInMagic;
  data[kVersionAt] = kProtocolVersion;
  data[kInChannelCountAt] = report.channel_count;
  usb_put_u16(data + kInSequenceAt, report.sequence);
  usb_put_u16(data + kInOutSequenceAt, report.out_sequence_applied);
  usb_put_u32(data + kInTimeAt, report.device_time_us);
  usb_put_u16(data + kInStatusAt, report.status);
  usb_put_u16(data + kInButtonsAt, report.buttons);
  for (std::size_t i = 0; i < kMaxChannels; ++i) {
    usb_put_i24(data + kInCountsAt + kWireCountBytes * i, report.counts[i]);
  }
  data[kReportSize - 1] = crc8(bytes.first(kReportSize - 1));
  return kReportSize;
}

DecodeStatus decode(std::span<const std::uint8_t> bytes, InReport& out) noexcept {
  const DecodeStatus envelope = usb_check_envelope(bytes, kReportSize, kInMagic);
  if (envelope != DecodeStatus::ok) return envelope;
  const std::uint8_t* data = bytes.data();
  const std::uint8_t channel_count = data[kInChannelCountAt];
  if (channel_count > kMaxChannels) return DecodeStatus::bad_channel_count;
  const std::size_t unused_at = kInCountsAt + kWireCountBytes * channel_count;
  if (!usb_all_zero(bytes.subspan(unused_at, kReportSize - 1 - unused_at))) {
    return DecodeStatus::reserved_not_zero;
  }
  InReport report;
  report.sequence = usb_get_u16(data + kInSequenceAt);
  report.out_sequence_applied = usb_get_u16(data + kInOutSequenceAt);
  report.device_time_us = usb_get_u32(data + kInTimeAt);
  report.status = usb_get_u16(data + kInStatusAt);
  report.buttons = usb_get_u16(data + kInButtonsAt);
  report.channel_count = channel_count;
  for (std::size_t i = 0; i < channel_count; ++i) {
    report.counts[i] = usb_get_i24(data + kInCountsAt + kWireCountBytes * i);
  }
  out = report;
  return DecodeStatus::ok;
}

// --- OUT -----------------------------------------------------------------------------------

std::size_t encode(const OutReport& report, std::span<std::uint8_t, kReportSize> bytes) noexcept {
  if (report.channel_count > kMaxChannels) return 0;
  if ((report.flags & ~kOutFlagsDefined) != 0) return 0;
  for (std::size_t i = report.channel_count; i < kMaxChannels; ++i) {
    if (report.current_ma[i] != 0) return 0;
  }
  std::fill(bytes.begin(), bytes.end(), std::uint8_t{0});
  std::uint8_t* data = bytes.data();
  data[0] = kOutMagic;
  data[kVersionAt] = kProtocolVersion;
  data[kOutChannelCountAt] = report.channel_count;
  data[kOutFlagsAt] = report.flags;
  usb_put_u16(data + kOutSequenceAt, report.sequence);
  for (std::size_t i = 0; i < kMaxChannels; ++i) {
    usb_put_u16(data + kOutCurrentsAt + 2 * i, static_cast<std::uint16_t>(report.current_ma[i]));
  }
  data[kReportSize - 1] = crc8(bytes.first(kReportSize - 1));
  return kReportSize;
}

DecodeStatus decode(std::span<const std::uint8_t> bytes, OutReport& out) noexcept {
  const DecodeStatus envelope = usb_check_envelope(bytes, kReportSize, kOutMagic);
  if (envelope != DecodeStatus::ok) return envelope;
  const std::uint8_t* data = bytes.data();
  const std::uint8_t channel_count = data[kOutChannelCountAt];
  if (channel_count > kMaxChannels) return DecodeStatus::bad_channel_count;
  const std::uint8_t flags = data[kOutFlagsAt];
  if ((flags & ~kOutFlagsDefined) != 0) return DecodeStatus::reserved_not_zero;
  const std::size_t unused_at = kOutCurrentsAt + 2 * std::size_t{channel_count};
  if (!usb_all_zero(bytes.subspan(unused_at, kReportSize - 1 - unused_at))) {
    return DecodeStatus::reserved_not_zero;
  }
  OutReport report;
  report.sequence = usb_get_u16(data + kOutSequenceAt);
  report.flags = flags;
  report.channel_count = channel_count;
  for (std::size_t i = 0; i < channel_count; ++i) {
    report.current_ma[i] = static_cast<std::int16_t>(usb_get_u16(data + kOutCurrentsAt + 2 * i));
  }
  out = report;
  return DecodeStatus::ok;
}

// --- identity ------------------------------------------------------------------------------

std::size_t encode(const Identity& identity, std::span<std::uint8_t, kIdentitySize> bytes) noexcept {
  if (identity.channel_count > kMaxChannels) return 0;
  if (identity.protocol_version != kProtocolVersion) return 0;
  std::fill(bytes.begin(), bytes.end(), std::uint8_t{0});
  std::uint8_t* data = bytes.data();
  data[0] = kIdentityMagic;
  data[kVersionAt] = identity.protocol_version;
  data[kIdChannelCountAt] = identity.channel_count;
  usb_put_u16(data + kIdFirmwareAt, identity.firmware_version);
  usb_put_u16(data + kIdWatchdogAt, identity.watchdog_ms);
  usb_put_u32(data + kIdFrameIntervalAt, identity.frame_interval_us);
  usb_put_u16(data + kIdMaxCurrentAt, identity.max_current_ma);
  data[kIdentitySize - 1] = crc8(bytes.first(kIdentitySize - 1));
  return kIdentitySize;
}

DecodeStatus decode(std::span<const std::uint8_t> bytes, Identity& out) noexcept {
  const DecodeStatus envelope = usb_check_envelope(bytes, kIdentitySize, kIdentityMagic);
  if (envelope != DecodeStatus::ok) return envelope;
  const std::uint8_t* data = bytes.data();
  if (data[kIdChannelCountAt] > kMaxChannels) return DecodeStatus::bad_channel_count;
  if (data[kIdReservedAt] != 0 || data[kIdReserved2At] != 0) return DecodeStatus::reserved_not_zero;
  Identity identity;
  identity.protocol_version = data[kVersionAt];
  identity.channel_count = data[kIdChannelCountAt];
  identity.firmware_version = usb_get_u16(data + kIdFirmwareAt);
  identity.watchdog_ms = usb_get_u16(data + kIdWatchdogAt);
  identity.frame_interval_us = usb_get_u32(data + kIdFrameIntervalAt);
  identity.max_current_ma = usb_get_u16(data + kIdMaxCurrentAt);
  out = identity;
  return DecodeStatus::ok;
}

}  // namespace trainer::hal::usbproto
