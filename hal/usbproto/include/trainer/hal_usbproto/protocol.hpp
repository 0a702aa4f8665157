// The USB haptic interface protocol (docs/usb-protocol.md): the two 64-byte interrupt
// reports, the identity returned by the vendor control request, the constants both sides
// share (VID:PID, requests, status and flag bits, limits) and sequence-number arithmetic.
//
// Host (libusb backend), per RT cycle:
//   OutReport out{.sequence = ++seq, .flags = kOutFlagEnable, .channel_count = n, ...};
//   encode(out, buffer);                          // -> the interrupt OUT transfer
//   InReport in;
//   if (decode(in_bytes, in) != DecodeStatus::ok) { ++rejected; ... }
//   counts = extend_count(previous_counts, in.counts[i]);   // 24-bit wire -> int64
// Device (tools/usbgadget), per exchanged OUT report:
//   decode(out_bytes, out) -> apply currents -> step plant -> encode(in, buffer) -> IN
//
// The library does no I/O: every type here is a value, every function noexcept and
// allocation-free. The wire layout is little-endian and written field by field (never a
// memcpy of a struct); every report carries a magic byte per direction, the protocol version
// and a CRC-8 so that garbage, a report of the other direction or of another version is
// refused rather than misread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace trainer::hal::usbproto {

// --- identity on the bus ------------------------------------------------------------------
// pid.codes test VID:PID (https://pid.codes/1209/0001/): for tests and benches only, never
// for a shipped product. The device is chosen by VID:PID and its serial number string.
inline constexpr std::uint16_t kVendorId = 0x1209;
inline constexpr std::uint16_t kProductId = 0x0001;
inline constexpr std::uint8_t kInterfaceClass = 0xFF;     // vendor specific
inline constexpr std::uint8_t kInterfaceSubClass = 0x00;
inline constexpr std::uint8_t kInterfaceProtocol = 0x00;

inline constexpr std::uint8_t kProtocolVersion = 1;

// --- sizes and limits ---------------------------------------------------------------------
inline constexpr std::size_t kMaxChannels = 16;
inline constexpr std::size_t kReportSize = 64;         // both directions, fixed size
inline constexpr std::uint16_t kMaxPacketSize = 64;    // wMaxPacketSize of both endpoints
// bInterval of both interrupt endpoints: full speed counts 1 ms frames, high speed counts
// 2^(bInterval-1) microframes of 125 us; both are 1 (poll every (micro)frame).
inline constexpr std::uint8_t kIntervalFullSpeed = 1;
inline constexpr std::uint8_t kIntervalHighSpeed = 1;

// Encoder counts travel as signed 24-bit numbers (16 channels x 4 bytes would not fit in
// 64 bytes with a header): the device sends its absolute count modulo 2^24, sign-extended
// into InReport::counts; the host extends them to 64 bits with extend_count().
inline constexpr std::int32_t kMinWireCount = -(1 << 23);
inline constexpr std::int32_t kMaxWireCount = (1 << 23) - 1;

// --- vendor control requests (bmRequestType vendor | interface recipient) -----------------
// GET_IDENTITY: bmRequestType 0xC1 (device-to-host), wValue 0, wIndex = interface number,
// wLength >= kIdentitySize; the device answers kIdentitySize bytes (encode(Identity)).
inline constexpr std::uint8_t kRequestGetIdentity = 0x01;
// SET_WATCHDOG: bmRequestType 0x41 (host-to-device), wValue = watchdog in ms
// (kMinWatchdogMs..kMaxWatchdogMs), wIndex = interface number, wLength 0. Refused (stall)
// outside the range; in force from the next applied OUT report on (so a request cannot trip
// the watchdog retroactively).
inline constexpr std::uint8_t kRequestSetWatchdog = 0x02;
inline constexpr std::uint8_t kRequestTypeVendorInterfaceIn = 0xC1;
inline constexpr std::uint8_t kRequestTypeVendorInterfaceOut = 0x41;
inline constexpr std::uint16_t kMinWatchdogMs = 2;
inline constexpr std::uint16_t kMaxWatchdogMs = 1000;

// --- IN report status bits (InReport::status) --------------------------------------------
// Latched: no valid OUT report for watchdog_ms while enabled; currents are zero until an OUT
// report with kOutFlagClearWatchdog (docs/usb-protocol.md "Device watchdog").
inline constexpr std::uint16_t kStatusWatchdogTripped = 1U << 0;
// The currents of the last applied OUT report are on the motors (enable set, no trip).
inline constexpr std::uint16_t kStatusEnabled = 1U << 1;
// The device has a fault of its own (plant/amplifier); currents are zero; latched until a
// clear-watchdog OUT report, like the trip.
inline constexpr std::uint16_t kStatusFault = 1U << 2;
// At least one current of the last applied OUT report exceeded the device's limit and was
// clipped to it (Identity::max_current_ma).
inline constexpr std::uint16_t kStatusCurrentLimited = 1U << 3;
// An OUT report since the previous IN report was refused by the decoder (not applied).
inline constexpr std::uint16_t kStatusOutRejected = 1U << 4;
// No new OUT report was applied since the previous IN report (out_sequence_applied repeats).
inline constexpr std::uint16_t kStatusNoNewOut = 1U << 5;

// --- OUT report flags (OutReport::flags); other bits are reserved and must be 0 -----------
inline constexpr std::uint8_t kOutFlagEnable = 1U << 0;
// Acknowledge a watchdog trip / device fault (sent by the host only after it saw the bit in
// an IN report and the operator reset): the latch clears, this report's currents are NOT
// applied; the next report with kOutFlagEnable applies currents again.
inline constexpr std::uint8_t kOutFlagClearWatchdog = 1U << 1;
inline constexpr std::uint8_t kOutFlagsDefined = kOutFlagEnable | kOutFlagClearWatchdog;

// --- the reports ---------------------------------------------------------------------------
// Device -> host, one per applied OUT report (and per device frame when idle).
struct InReport {
  std::uint16_t sequence = 0;              // +1 per IN report, wraps at 2^16
  std::uint16_t out_sequence_applied = 0;  // sequence of the last OUT report the device applied
  std::uint32_t device_time_us = 0;        // device clock (plant time), wraps at 2^32 us
  std::uint16_t status = 0;                // kStatus* bits
  std::uint16_t buttons = 0;               // bit i = handle button / digital input i
  std::uint8_t channel_count = 0;          // 0..kMaxChannels
  // counts[0 .. channel_count): absolute encoder counts modulo 2^24, kMinWireCount ..
  // kMaxWireCount; entries at and above channel_count are 0.
  std::int32_t counts[kMaxChannels] = {};
};

// Host -> device, one per host cycle.
struct OutReport {
  std::uint16_t sequence = 0;     // +1 per OUT report, wraps at 2^16
  std::uint8_t flags = 0;         // kOutFlag* bits
  std::uint8_t channel_count = 0;  // 0..kMaxChannels; must equal the device's channel count
  // current_ma[0 .. channel_count): motor current setpoints, mA; entries at and above
  // channel_count are 0.
  std::int16_t current_ma[kMaxChannels] = {};
};

// Answer to kRequestGetIdentity.
inline constexpr std::size_t kIdentitySize = 16;
struct Identity {
  std::uint8_t protocol_version = kProtocolVersion;
  std::uint16_t firmware_version = 0;  // major << 8 | minor
  std::uint8_t channel_count = 0;      // 1..kMaxChannels on a real device
  std::uint16_t watchdog_ms = 0;       // device watchdog set (in force from the next OUT report)
  std::uint32_t frame_interval_us = 0;  // plant time the device advances per exchange
  std::uint16_t max_current_ma = 0;     // per-channel current limit the device clips to
};

enum class DecodeStatus : std::uint8_t {
  ok,
  wrong_length,       // not exactly kReportSize (kIdentitySize) bytes
  bad_magic,          // first byte is not this report's magic (other direction, garbage)
  bad_version,        // protocol version byte != kProtocolVersion
  bad_checksum,       // CRC-8 over the report does not match its last byte
  bad_channel_count,  // channel_count > kMaxChannels
  reserved_not_zero,  // a reserved byte/flag bit or an unused channel slot is not 0
};
const char* to_string(DecodeStatus status) noexcept;

// Magic bytes (first byte of each report): 'I', 'O', 'D' in a hex dump.
inline constexpr std::uint8_t kInMagic = 0x49;
inline constexpr std::uint8_t kOutMagic = 0x4F;
inline constexpr std::uint8_t kIdentityMagic = 0x44;

// encode(): writes the whole buffer and returns its size, or returns 0 (buffer content
// unspecified) when the value cannot be sent: channel_count > kMaxChannels, a count outside
// kMinWireCount..kMaxWireCount, an unused slot not 0, undefined OUT flag bits.
// decode(): `out` is written only when the status is ok.
std::size_t encode(const InReport& report, std::span<std::uint8_t, kReportSize> bytes) noexcept;
DecodeStatus decode(std::span<const std::uint8_t> bytes, InReport& out) noexcept;
std::size_t encode(const OutReport& report, std::span<std::uint8_t, kReportSize> bytes) noexcept;
DecodeStatus decode(std::span<const std::uint8_t> bytes, OutReport& out) noexcept;
std::size_t encode(const Identity& identity, std::span<std::uint8_t, kIdentitySize> bytes) noexcept;
DecodeStatus decode(std::span<const std::uint8_t> bytes, Identity& out) noexcept;

// CRC-8/SMBUS (polynomial 0x07, init 0, no reflection, no xor-out; check("123456789") =
// 0xF4): the last byte of every report and of the identity, over all bytes before it.
std::uint8_t crc8(std::span<const std::uint8_t> bytes) noexcept;

// --- sequence numbers and counts ----------------------------------------------------------
// How far `newer` is ahead of `older` modulo 2^16 (0 = same report). A host that sent OUT
// sequence s and reads out_sequence_applied a: sequence_distance(s, a) reports in flight.
constexpr std::uint16_t sequence_distance(std::uint16_t newer, std::uint16_t older) noexcept {
  return static_cast<std::uint16_t>(newer - older);
}

// The device's absolute count as it goes on the wire (modulo 2^24, sign-extended).
constexpr std::int32_t wire_count(std::int64_t absolute_count) noexcept {
  const auto low = static_cast<std::uint32_t>(static_cast<std::uint64_t>(absolute_count) & 0xFFFFFFU);
  return low >= 0x800000U ? static_cast<std::int32_t>(low) - (1 << 24) : static_cast<std::int32_t>(low);
}

// The 64-bit count nearest to `previous` whose wire value is `wire` (the host's unwrapping):
// exact as long as the count moved less than 2^23 between two reports.
constexpr std::int64_t extend_count(std::int64_t previous, std::int32_t wire) noexcept {
  const std::int32_t delta = wire_count(static_cast<std::int64_t>(wire) - wire_count(previous));
  return previous + delta;
}

}  // namespace trainer::hal::usbproto
