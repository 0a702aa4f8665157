// Process data objects (CiA 301 v4.2, 7.2.2 and 7.5.2.35-38): mapping entries, a PdoMapping
// that packs values into / unpacks them from frame data, communication parameter helpers,
// and the master's SDO write sequence that configures one PDO on a slave.
//
// Mapping (master and slave):
//   PdoMapping rx;                                   // RPDO1 of a CST drive
//   rx.add(0x6040, 0, 16, false);                    // controlword
//   rx.add(0x6071, 0, 16, true);                     // target torque (signed)
//   const std::int64_t values[2] = {0x0F, -250};
//   can_frame frame = make_frame(cob_id(FrameKind::rpdo, node, 1), {});
//   rx.pack(values, frame);                          // data + len; can_id untouched
//   tx.unpack(received, out_values);                 // sign-extended for signed fields
// Configuration (master, before NMT start, through SdoClient):
//   PdoConfiguration config{.direction = PdoDirection::receive, .pdo_number = 1,
//                           .can_id = cob_id(FrameKind::rpdo, node, 1), .transmission_type = 1};
//   config.mapping = rx;
//   core::FixedVector<SdoWrite, kMaxPdoConfigurationWrites> writes;
//   pdo_configuration_writes(config, writes);
//   for (const SdoWrite& w : writes) sdo.start_download(node, w.index, w.sub, w.bytes(), now) ... in turn
//
// Transmission type (sub 2): 0 synchronous acyclic, 1..240 synchronous every n-th SYNC
// (an RPDO's data is applied at the next SYNC), 252/253 RTR only (not supported here),
// 254 event-driven (manufacturer), 255 event-driven (device profile); 241..251 reserved.
// Inhibit time (sub 3, TPDO only): minimum gap between transmissions, in 100 us units.
// Event timer (sub 5, ms, 0 = off): for a TPDO the period of event-driven transmission;
// for an RPDO CiA 301 uses it as DEADLINE MONITORING: when no RPDO arrived within the
// time, the slave reports EMCY 0x8250 (RPDO timeout) and may react (CiA 402: 0x6007).
#pragma once

#include <linux/can.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

#include "trainer/core/fixed_vector.hpp"
#include "trainer/core/status.hpp"

namespace trainer::hal::canopen {

enum class PdoDirection : std::uint8_t {
  receive,   // RPDO: master -> slave (0x1400 / 0x1600)
  transmit,  // TPDO: slave -> master (0x1800 / 0x1A00)
};

// --- mapping entries (0x1600.. / 0x1A00.. sub 1..64): index << 16 | sub << 8 | bit length ---
struct PdoMappingEntry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bits = 0;
};
constexpr std::uint32_t encode_mapping_entry(const PdoMappingEntry& entry) noexcept {
  return (static_cast<std::uint32_t>(entry.index) << 16) | (static_cast<std::uint32_t>(entry.sub) << 8) |
         entry.bits;
}
constexpr PdoMappingEntry decode_mapping_entry(std::uint32_t value) noexcept {
  return {static_cast<std::uint16_t>(value >> 16), static_cast<std::uint8_t>((value >> 8) & 0xFFU),
          static_cast<std::uint8_t>(value & 0xFFU)};
}

struct PdoField {
  PdoMappingEntry object;
  bool is_signed = false;
  std::uint8_t byte_offset = 0;  // position in the frame data
};

// Whether a received PDO's length fits its mapping (CiA 301 7.2.2.2).
enum class PdoLength : std::uint8_t {
  ok,
  too_short,  // not processed; EMCY 0x8210
  too_long,   // processed (the first bytes are used); EMCY 0x8220 may be sent
};

// Up to 8 byte-aligned objects, 64 bits in all, packed little-endian in mapping order.
class PdoMapping {
 public:
  static constexpr std::size_t kMaxEntries = 8;
  static constexpr unsigned kMaxBits = 64;

  // invalid_argument unless bits is 8, 16, 24, ... 64; capacity_exceeded past 8 entries or
  // 64 bits (the mapping is unchanged then).
  core::Status add(std::uint16_t index, std::uint8_t sub, std::uint8_t bits, bool is_signed) noexcept;
  void clear() noexcept { count_ = 0; total_bits_ = 0; }

  std::size_t size() const noexcept { return count_; }
  unsigned total_bits() const noexcept { return total_bits_; }
  std::uint8_t byte_length() const noexcept { return static_cast<std::uint8_t>(total_bits_ / 8); }
  std::span<const PdoField> fields() const noexcept { return {fields_.data(), count_}; }
  const PdoField& operator[](std::size_t i) const noexcept { return fields_[i]; }

  // Writes values[i] into field i (values.size() must equal size()); sets frame.len to
  // byte_length() and zeroes the unused bytes. invalid_argument when a value does not fit
  // its field (a 16-bit unsigned field takes 0..65535, signed -32768..32767; 64-bit fields
  // take any value as its two's complement bit pattern).
  core::Status pack(std::span<const std::int64_t> values, can_frame& frame) const noexcept;
  // Reads every field (values.size() must equal size()), sign-extending signed fields.
  // invalid_argument when the frame is shorter than byte_length().
  core::Status unpack(const can_frame& frame, std::span<std::int64_t> values) const noexcept;
  PdoLength check_length(const can_frame& frame) const noexcept;

 private:
  std::array<PdoField, kMaxEntries> fields_{};
  std::size_t count_ = 0;
  unsigned total_bits_ = 0;
};

// --- communication parameters (0x1400.. / 0x1800..) ---------------------------------------------
inline constexpr std::uint32_t kPdoCobIdInvalid = 0x80000000;  // bit 31: PDO does not exist / not valid
inline constexpr std::uint32_t kPdoCobIdNoRtr = 0x40000000;    // bit 30: no RTR allowed on this PDO
inline constexpr std::uint32_t kPdoCobIdExtended = 0x20000000;  // bit 29: 29-bit id (not supported)

inline constexpr std::uint8_t kTransmissionSynchronousAcyclic = 0;
inline constexpr std::uint8_t kTransmissionSynchronousMax = 240;
inline constexpr std::uint8_t kTransmissionRtrSynchronous = 252;
inline constexpr std::uint8_t kTransmissionRtrEvent = 253;
inline constexpr std::uint8_t kTransmissionEventManufacturer = 254;
inline constexpr std::uint8_t kTransmissionEventProfile = 255;
constexpr bool is_synchronous_transmission(std::uint8_t type) noexcept { return type <= kTransmissionSynchronousMax; }
constexpr bool is_event_transmission(std::uint8_t type) noexcept { return type >= kTransmissionEventManufacturer; }

constexpr std::uint32_t encode_pdo_cob_id(std::uint16_t can_id, bool valid, bool rtr_allowed = false) noexcept {
  return (can_id & 0x7FFU) | (valid ? 0U : kPdoCobIdInvalid) | (rtr_allowed ? 0U : kPdoCobIdNoRtr);
}
struct PdoCobId {
  std::uint16_t can_id = 0;
  bool valid = false;
  bool rtr_allowed = false;
  bool extended = false;  // bit 29 set: not usable with this library
};
constexpr PdoCobId decode_pdo_cob_id(std::uint32_t value) noexcept {
  return {static_cast<std::uint16_t>(value & 0x7FFU), (value & kPdoCobIdInvalid) == 0, (value & kPdoCobIdNoRtr) == 0,
          (value & kPdoCobIdExtended) != 0};
}

// 0x1400 + n - 1 (RPDO) / 0x1800 + n - 1 (TPDO), n = 1..512; 0 when n is out of range.
std::uint16_t pdo_communication_index(PdoDirection direction, std::uint16_t pdo_number) noexcept;
// 0x1600 + n - 1 (RPDO) / 0x1A00 + n - 1 (TPDO).
std::uint16_t pdo_mapping_index(PdoDirection direction, std::uint16_t pdo_number) noexcept;

// --- the master's configuration sequence -------------------------------------------------------
struct PdoConfiguration {
  PdoDirection direction = PdoDirection::receive;
  std::uint16_t pdo_number = 1;  // 1..512
  std::uint16_t can_id = 0;      // 11-bit id, e.g. cob_id(FrameKind::rpdo, node, 1)
  bool rtr_allowed = false;
  std::uint8_t transmission_type = kTransmissionEventProfile;
  std::optional<std::uint16_t> inhibit_time_100us;  // TPDO only; written when set
  std::optional<std::uint16_t> event_timer_ms;      // written when set (RPDO: deadline)
  PdoMapping mapping;
};

// One SDO expedited write: `size` little-endian bytes of `value` to index:sub.
struct SdoWrite {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t size = 0;  // 1, 2 or 4
  std::uint32_t value = 0;
  std::array<std::uint8_t, 4> data{};  // value as sent
  std::span<const std::uint8_t> bytes() const noexcept { return {data.data(), size}; }
};
SdoWrite make_sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) noexcept;

inline constexpr std::size_t kMaxPdoConfigurationWrites = 7 + PdoMapping::kMaxEntries;

// The writes, in order, that configure a PDO (CiA 301 7.5.2.35/36 mapping procedure):
//   1. COB-ID with bit 31 set (PDO not valid; the new id already in bits 0..10)
//   2. transmission type           3. inhibit time (TPDO, if set)   4. event timer (if set)
//   5. mapping sub 0 = 0 (mapping disabled)
//   6. mapping sub 1..n = entries  7. mapping sub 0 = n
//   8. COB-ID with bit 31 clear (PDO valid)
// `out` is cleared first. invalid_argument for a pdo_number outside 1..512, a CAN id
// outside 0x001..0x7FF or a reserved transmission type (241..251); capacity_exceeded when
// `out` is too small (kMaxPdoConfigurationWrites always suffices).
core::Status pdo_configuration_writes(const PdoConfiguration& config, core::FixedVectorRef<SdoWrite>& out) noexcept;

// The writes that disable a PDO (COB-ID with bit 31 set), e.g. unused TPDO2..4.
SdoWrite pdo_disable_write(PdoDirection direction, std::uint16_t pdo_number, std::uint16_t can_id) noexcept;

}  // namespace trainer::hal::canopen
