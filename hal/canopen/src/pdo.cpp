// PDO mapping, packing and the configuration sequence (CiA 301 v4.2, 7.2.2, 7.5.2.35-38).
#include "trainer/hal_canopen/pdo.hpp"

#include <algorithm>

#include "bytes.hpp"

namespace trainer::hal::canopen {

namespace {

constexpr std::uint16_t kRpdoCommunicationBase = 0x1400;
constexpr std::uint16_t kRpdoMappingBase = 0x1600;
constexpr std::uint16_t kTpdoCommunicationBase = 0x1800;
constexpr std::uint16_t kTpdoMappingBase = 0x1A00;
constexpr std::uint16_t kMaxPdoNumber = 512;
constexpr std::uint8_t kSubCobId = 1;
constexpr std::uint8_t kSubTransmissionType = 2;
constexpr std::uint8_t kSubInhibitTime = 3;
constexpr std::uint8_t kSubEventTimer = 5;

bool fits_field(const PdoField& field, std::int64_t value) noexcept {
  const unsigned bits = field.object.bits;
  if (bits >= 64) return true;
  if (field.is_signed) {
    const std::int64_t limit = std::int64_t{1} << (bits - 1);
    return value >= -limit && value < limit;
  }
  return value >= 0 && value < (std::int64_t{1} << bits);
}

}  // namespace

core::Status PdoMapping::add(std::uint16_t index, std::uint8_t sub, std::uint8_t bits, bool is_signed) noexcept {
  if (bits == 0 || bits % 8 != 0 || bits > kMaxBits) {
    return {core::StatusCode::invalid_argument, "PDO mapping: bit length must be 8, 16, ... 64 (byte-aligned)"};
  }
  if (count_ == kMaxEntries) return {core::StatusCode::capacity_exceeded, "PDO mapping: more than 8 entries"};
  if (total_bits_ + bits > kMaxBits) return {core::StatusCode::capacity_exceeded, "PDO mapping: more than 64 bits"};
  fields_[count_++] = PdoField{{index, sub, bits}, is_signed, static_cast<std::uint8_t>(total_bits_ / 8)};
  total_bits_ += bits;
  return core::Status::ok();
}

core::Status PdoMapping::pack(std::span<const std::int64_t> values, can_frame& frame) const noexcept {
  if (values.size() != count_) return {core::StatusCode::invalid_argument, "PDO pack: one value per field"};
  for (std::size_t i = 0; i < count_; ++i) {
    if (!fits_field(fields_[i], values[i])) {
      return {core::StatusCode::invalid_argument, "PDO pack: value does not fit its field"};
    }
  }
  // The fields assembled in one little-endian 64-bit payload, written as the frame's 8 bytes
  // (a byte loop per field at frame.data + offset trips GCC 12's -Wstringop-overflow false
  // positive once vectorised for x86-64-v3).
  std::uint64_t payload = 0;
  for (std::size_t i = 0; i < count_; ++i) {
    const PdoField& field = fields_[i];
    const std::uint64_t mask =
        field.object.bits >= 64U ? ~std::uint64_t{0} : (std::uint64_t{1} << field.object.bits) - 1U;
    payload |= (static_cast<std::uint64_t>(values[i]) & mask) << (8U * field.byte_offset);
  }
  detail::put_le(frame.data, sizeof frame.data, payload);
  frame.len = byte_length();
  return core::Status::ok();
}

PdoLength PdoMapping::check_length(const can_frame& frame) const noexcept {
  if (frame.len < byte_length()) return PdoLength::too_short;
  if (frame.len > byte_length()) return PdoLength::too_long;
  return PdoLength::ok;
}

core::Status PdoMapping::unpack(const can_frame& frame, std::span<std::int64_t> values) const noexcept {
  if (values.size() != count_) return {core::StatusCode::invalid_argument, "PDO unpack: one value per field"};
  if (frame.len < byte_length() || frame.len > CAN_MAX_DLEN) {
    return {core::StatusCode::invalid_argument, "PDO unpack: frame shorter than the mapping"};
  }
  for (std::size_t i = 0; i < count_; ++i) {
    const PdoField& field = fields_[i];
    const unsigned bits = field.object.bits;
    std::uint64_t raw = detail::get_le(frame.data + field.byte_offset, bits / 8U);
    if (field.is_signed && bits < 64) {
      const std::uint64_t sign_bit = std::uint64_t{1} << (bits - 1);
      if ((raw & sign_bit) != 0) raw |= ~((sign_bit << 1) - 1);
    }
    values[i] = static_cast<std::int64_t>(raw);
  }
  return core::Status::ok();
}

std::uint16_t pdo_communication_index(PdoDirection direction, std::uint16_t pdo_number) noexcept {
  if (pdo_number < 1 || pdo_number > kMaxPdoNumber) return 0;
  const std::uint16_t base = direction == PdoDirection::receive ? kRpdoCommunicationBase : kTpdoCommunicationBase;
  return static_cast<std::uint16_t>(base + pdo_number - 1);
}

std::uint16_t pdo_mapping_index(PdoDirection direction, std::uint16_t pdo_number) noexcept {
  if (pdo_number < 1 || pdo_number > kMaxPdoNumber) return 0;
  const std::uint16_t base = direction == PdoDirection::receive ? kRpdoMappingBase : kTpdoMappingBase;
  return static_cast<std::uint16_t>(base + pdo_number - 1);
}

SdoWrite make_sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) noexcept {
  SdoWrite write;
  write.index = index;
  write.sub = sub;
  write.size = std::min<std::uint8_t>(size, 4);
  write.value = value;
  detail::put_le(write.data.data(), write.size, value);
  return write;
}

SdoWrite pdo_disable_write(PdoDirection direction, std::uint16_t pdo_number, std::uint16_t can_id) noexcept {
  return make_sdo_write(pdo_communication_index(direction, pdo_number), kSubCobId,
                        encode_pdo_cob_id(can_id, false), 4);
}

core::Status pdo_configuration_writes(const PdoConfiguration& config, core::FixedVectorRef<SdoWrite>& out) noexcept {
  out.clear();
  const std::uint16_t communication = pdo_communication_index(config.direction, config.pdo_number);
  const std::uint16_t mapping = pdo_mapping_index(config.direction, config.pdo_number);
  if (communication == 0) return {core::StatusCode::invalid_argument, "PDO configuration: pdo_number outside 1..512"};
  if (config.can_id == 0 || config.can_id > 0x7FF) {
    return {core::StatusCode::invalid_argument, "PDO configuration: CAN id outside 0x001..0x7FF"};
  }
  if (config.transmission_type > kTransmissionSynchronousMax && config.transmission_type < kTransmissionRtrSynchronous) {
    return {core::StatusCode::invalid_argument, "PDO configuration: transmission type 241..251 is reserved"};
  }
  bool fits = out.push_back(make_sdo_write(communication, kSubCobId,
                                           encode_pdo_cob_id(config.can_id, false, config.rtr_allowed), 4));
  fits = fits && out.push_back(make_sdo_write(communication, kSubTransmissionType, config.transmission_type, 1));
  if (config.direction == PdoDirection::transmit && config.inhibit_time_100us) {
    fits = fits && out.push_back(make_sdo_write(communication, kSubInhibitTime, *config.inhibit_time_100us, 2));
  }
  if (config.event_timer_ms) {
    fits = fits && out.push_back(make_sdo_write(communication, kSubEventTimer, *config.event_timer_ms, 2));
  }
  fits = fits && out.push_back(make_sdo_write(mapping, 0, 0, 1));
  for (std::size_t i = 0; i < config.mapping.size(); ++i) {
    fits = fits && out.push_back(make_sdo_write(mapping, static_cast<std::uint8_t>(i + 1),
                                                encode_mapping_entry(config.mapping[i].object), 4));
  }
  fits = fits && out.push_back(make_sdo_write(mapping, 0, static_cast<std::uint32_t>(config.mapping.size()), 1));
  fits = fits && out.push_back(make_sdo_write(communication, kSubCobId,
                                              encode_pdo_cob_id(config.can_id, true, config.rtr_allowed), 4));
  if (!fits) {
    out.clear();
    return {core::StatusCode::capacity_exceeded, "PDO configuration: output list too small"};
  }
  return core::Status::ok();
}

}  // namespace trainer::hal::canopen
