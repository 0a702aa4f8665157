// PDOs (CiA 301 v4.2, 7.2.2, 7.5.2.35-38): mapping entries, packing with sign extension,
// length checks, COB-ID and transmission type coding, the master's configuration sequence,
// and that sequence run through SdoClient against a slave dictionary that checks it.
#include <array>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/fixed_vector.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_canopen/pdo_dictionary.hpp"
#include "trainer/hal_canopen/sdo.hpp"
#include "trainer/hal_canopen/sdo_client.hpp"
#include "trainer/hal_canopen/sdo_server.hpp"

namespace trainer::hal::canopen {
namespace {

constexpr std::uint8_t kPdoNode = 5;

TEST(Pdo, MappingEntryCoding) {
  EXPECT_EQ(encode_mapping_entry({0x6040, 0x00, 16}), 0x60400010U);
  EXPECT_EQ(encode_mapping_entry({0x6071, 0x00, 16}), 0x60710010U);
  EXPECT_EQ(encode_mapping_entry({0x1018, 0x04, 32}), 0x10180420U);
  const PdoMappingEntry entry = decode_mapping_entry(0x60640020U);
  EXPECT_EQ(entry.index, 0x6064);
  EXPECT_EQ(entry.sub, 0);
  EXPECT_EQ(entry.bits, 32);
}

TEST(Pdo, PackIsLittleEndianAndUnpackSignExtends) {
  PdoMapping mapping;
  ASSERT_TRUE(mapping.add(0x6040, 0, 16, false).is_ok());
  ASSERT_TRUE(mapping.add(0x6071, 0, 16, true).is_ok());
  ASSERT_TRUE(mapping.add(0x6064, 0, 32, true).is_ok());
  EXPECT_EQ(mapping.total_bits(), 64U);
  EXPECT_EQ(mapping.byte_length(), 8);
  const std::int64_t values[3] = {0x000F, -250, -123456};
  can_frame frame = make_frame(0x205, {});
  ASSERT_TRUE(mapping.pack(values, frame).is_ok());
  EXPECT_EQ(frame.can_id, 0x205U);
  ASSERT_EQ(frame.len, 8);
  const std::uint8_t expected[8] = {0x0F, 0x00, 0x06, 0xFF, 0xC0, 0x1D, 0xFE, 0xFF};
  EXPECT_EQ(std::memcmp(frame.data, expected, 8), 0);
  std::int64_t out[3] = {};
  ASSERT_TRUE(mapping.unpack(frame, out).is_ok());
  EXPECT_EQ(out[0], 0x000F);
  EXPECT_EQ(out[1], -250);
  EXPECT_EQ(out[2], -123456);
  // The same bytes read as unsigned fields are not sign-extended.
  PdoMapping unsigned_mapping;
  ASSERT_TRUE(unsigned_mapping.add(0x2000, 1, 16, false).is_ok());
  ASSERT_TRUE(unsigned_mapping.add(0x2000, 2, 16, false).is_ok());
  ASSERT_TRUE(unsigned_mapping.add(0x2000, 3, 32, false).is_ok());
  ASSERT_TRUE(unsigned_mapping.unpack(frame, out).is_ok());
  EXPECT_EQ(out[1], 0xFF06);
  EXPECT_EQ(out[2], 0xFFFE1DC0);
}

TEST(Pdo, RandomRoundTripsOverFieldWidths) {
  std::mt19937_64 random(7);
  for (int trial = 0; trial < 2000; ++trial) {
    PdoMapping mapping;
    std::vector<std::int64_t> values;
    unsigned bits_left = 64;
    while (bits_left >= 8 && mapping.size() < PdoMapping::kMaxEntries) {
      const unsigned bytes = 1 + static_cast<unsigned>(random() % std::min(4U, bits_left / 8));
      const unsigned bits = bytes * 8;
      const bool is_signed = (random() & 1U) != 0;
      ASSERT_TRUE(mapping.add(0x2000, static_cast<std::uint8_t>(mapping.size()), static_cast<std::uint8_t>(bits),
                              is_signed)
                      .is_ok());
      const std::uint64_t raw = random() & ((std::uint64_t{1} << bits) - 1);
      std::int64_t value = static_cast<std::int64_t>(raw);
      if (is_signed && (raw >> (bits - 1)) != 0) value -= std::int64_t{1} << bits;
      values.push_back(value);
      bits_left -= bits;
      if (random() % 4 == 0) break;
    }
    can_frame frame{};
    ASSERT_TRUE(mapping.pack(values, frame).is_ok());
    EXPECT_EQ(frame.len, mapping.byte_length());
    std::vector<std::int64_t> out(values.size());
    ASSERT_TRUE(mapping.unpack(frame, out).is_ok());
    EXPECT_EQ(out, values);
  }
}

TEST(Pdo, MappingLimitsAndValueRanges) {
  PdoMapping mapping;
  EXPECT_EQ(mapping.add(0x2000, 0, 12, false).code(), core::StatusCode::invalid_argument);  // not byte-aligned
  EXPECT_EQ(mapping.add(0x2000, 0, 0, false).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(mapping.add(0x2000, 0, 72, false).code(), core::StatusCode::invalid_argument);
  for (std::uint8_t i = 0; i < 8; ++i) ASSERT_TRUE(mapping.add(0x2000, i, 8, false).is_ok());
  EXPECT_EQ(mapping.add(0x2000, 8, 8, false).code(), core::StatusCode::capacity_exceeded);  // 9th entry
  PdoMapping wide;
  ASSERT_TRUE(wide.add(0x2000, 1, 32, false).is_ok());
  ASSERT_TRUE(wide.add(0x2000, 2, 24, false).is_ok());
  EXPECT_EQ(wide.add(0x2000, 3, 16, false).code(), core::StatusCode::capacity_exceeded);  // 72 bits
  EXPECT_EQ(wide.size(), 2U);

  PdoMapping fields;
  ASSERT_TRUE(fields.add(0x2000, 1, 8, false).is_ok());
  ASSERT_TRUE(fields.add(0x2000, 2, 16, true).is_ok());
  can_frame frame{};
  const std::int64_t ok_values[2] = {255, -32768};
  EXPECT_TRUE(fields.pack(ok_values, frame).is_ok());
  const std::int64_t too_big[2] = {256, 0};
  EXPECT_FALSE(fields.pack(too_big, frame).is_ok());
  const std::int64_t negative_unsigned[2] = {-1, 0};
  EXPECT_FALSE(fields.pack(negative_unsigned, frame).is_ok());
  const std::int64_t too_small[2] = {0, -32769};
  EXPECT_FALSE(fields.pack(too_small, frame).is_ok());
  const std::int64_t one_value[1] = {0};
  EXPECT_FALSE(fields.pack(one_value, frame).is_ok());

  // Length checks of received PDOs.
  frame.len = 3;
  EXPECT_EQ(fields.check_length(frame), PdoLength::ok);
  std::int64_t out[2] = {};
  frame.len = 2;
  EXPECT_EQ(fields.check_length(frame), PdoLength::too_short);
  EXPECT_FALSE(fields.unpack(frame, out).is_ok());
  frame.len = 8;
  EXPECT_EQ(fields.check_length(frame), PdoLength::too_long);
  EXPECT_TRUE(fields.unpack(frame, out).is_ok());
}

TEST(Pdo, CommunicationParameterCoding) {
  EXPECT_EQ(encode_pdo_cob_id(0x205, true), 0x40000205U);  // valid, no RTR
  EXPECT_EQ(encode_pdo_cob_id(0x205, false), 0xC0000205U);
  EXPECT_EQ(encode_pdo_cob_id(0x185, true, true), 0x00000185U);
  const PdoCobId decoded = decode_pdo_cob_id(0xC0000385U);
  EXPECT_EQ(decoded.can_id, 0x385);
  EXPECT_FALSE(decoded.valid);
  EXPECT_FALSE(decoded.rtr_allowed);
  EXPECT_FALSE(decoded.extended);
  EXPECT_TRUE(decode_pdo_cob_id(0x20000185U).extended);
  EXPECT_TRUE(is_synchronous_transmission(0));
  EXPECT_TRUE(is_synchronous_transmission(240));
  EXPECT_FALSE(is_synchronous_transmission(241));
  EXPECT_TRUE(is_event_transmission(254));
  EXPECT_TRUE(is_event_transmission(255));
  EXPECT_FALSE(is_event_transmission(253));
  EXPECT_EQ(pdo_communication_index(PdoDirection::receive, 1), 0x1400);
  EXPECT_EQ(pdo_communication_index(PdoDirection::transmit, 4), 0x1803);
  EXPECT_EQ(pdo_mapping_index(PdoDirection::receive, 2), 0x1601);
  EXPECT_EQ(pdo_mapping_index(PdoDirection::transmit, 512), 0x1BFF);
  EXPECT_EQ(pdo_mapping_index(PdoDirection::transmit, 0), 0);
  EXPECT_EQ(pdo_mapping_index(PdoDirection::transmit, 513), 0);
}

struct Write {
  std::uint16_t index;
  std::uint8_t sub;
  std::uint32_t value;
  std::uint8_t size;
  bool operator==(const Write&) const = default;
};

std::vector<Write> plain(const core::FixedVectorRef<SdoWrite>& writes) {
  std::vector<Write> result;
  for (const SdoWrite& w : writes) result.push_back({w.index, w.sub, w.value, w.size});
  return result;
}

TEST(Pdo, ConfigurationSequence) {
  PdoConfiguration rpdo;
  rpdo.direction = PdoDirection::receive;
  rpdo.pdo_number = 1;
  rpdo.can_id = cob_id(FrameKind::rpdo, kPdoNode, 1);
  rpdo.transmission_type = 1;
  rpdo.event_timer_ms = 100;  // deadline monitoring
  rpdo.inhibit_time_100us = 50;  // ignored for an RPDO
  ASSERT_TRUE(rpdo.mapping.add(0x6040, 0, 16, false).is_ok());
  ASSERT_TRUE(rpdo.mapping.add(0x6071, 0, 16, true).is_ok());
  core::FixedVector<SdoWrite, kMaxPdoConfigurationWrites> writes;
  ASSERT_TRUE(pdo_configuration_writes(rpdo, writes).is_ok());
  const std::vector<Write> expected = {
      {0x1400, 1, 0xC0000205, 4}, {0x1400, 2, 1, 1},          {0x1400, 5, 100, 2},
      {0x1600, 0, 0, 1},          {0x1600, 1, 0x60400010, 4}, {0x1600, 2, 0x60710010, 4},
      {0x1600, 0, 2, 1},          {0x1400, 1, 0x40000205, 4},
  };
  EXPECT_EQ(plain(writes), expected);
  const std::uint8_t cob_bytes[4] = {0x05, 0x02, 0x00, 0xC0};
  ASSERT_EQ(writes[0].bytes().size(), 4U);
  EXPECT_EQ(std::memcmp(writes[0].bytes().data(), cob_bytes, 4), 0);

  PdoConfiguration tpdo;
  tpdo.direction = PdoDirection::transmit;
  tpdo.pdo_number = 2;
  tpdo.can_id = cob_id(FrameKind::tpdo, kPdoNode, 2);
  tpdo.transmission_type = kTransmissionEventProfile;
  tpdo.inhibit_time_100us = 10;
  ASSERT_TRUE(tpdo.mapping.add(0x6041, 0, 16, false).is_ok());
  ASSERT_TRUE(pdo_configuration_writes(tpdo, writes).is_ok());
  const std::vector<Write> expected_tpdo = {
      {0x1801, 1, 0xC0000285, 4}, {0x1801, 2, 255, 1}, {0x1801, 3, 10, 2},         {0x1A01, 0, 0, 1},
      {0x1A01, 1, 0x60410010, 4}, {0x1A01, 0, 1, 1},   {0x1801, 1, 0x40000285, 4},
  };
  EXPECT_EQ(plain(writes), expected_tpdo);

  // Full mapping fits the declared capacity; errors leave the list empty.
  PdoConfiguration full = tpdo;
  full.event_timer_ms = 5;
  full.mapping.clear();
  for (std::uint8_t i = 0; i < 8; ++i) ASSERT_TRUE(full.mapping.add(0x2000, i, 8, false).is_ok());
  ASSERT_TRUE(pdo_configuration_writes(full, writes).is_ok());
  EXPECT_EQ(writes.size(), kMaxPdoConfigurationWrites);
  core::FixedVector<SdoWrite, 4> small;
  EXPECT_EQ(pdo_configuration_writes(full, small).code(), core::StatusCode::capacity_exceeded);
  EXPECT_TRUE(small.empty());
  PdoConfiguration reserved = tpdo;
  reserved.transmission_type = 245;
  EXPECT_EQ(pdo_configuration_writes(reserved, writes).code(), core::StatusCode::invalid_argument);
  PdoConfiguration bad_number = tpdo;
  bad_number.pdo_number = 0;
  EXPECT_FALSE(pdo_configuration_writes(bad_number, writes).is_ok());
  EXPECT_EQ(plain(core::FixedVector<SdoWrite, 1>{}).size(), 0U);
  const SdoWrite disable = pdo_disable_write(PdoDirection::transmit, 3, 0x385);
  EXPECT_EQ((Write{disable.index, disable.sub, disable.value, disable.size}), (Write{0x1802, 1, 0xC0000385, 4}));
}

// A slave dictionary with RPDO1's parameters whose observer applies the CiA 301 rules: the
// COB-ID may change only while the PDO is invalid, the mapping only while the PDO is
// invalid and sub 0 is 0, and sub 0 = n is checked against the dictionary.
class RpdoSlave final : public ObjectDictionaryObserver {
 public:
  RpdoSlave() {
    auto add = [this](ObjectDefinition d) { EXPECT_TRUE(od.add(d)); };
    add({.index = 0x1400, .sub = 0, .type = DataType::u8, .access = Access::constant, .value = 5});
    add({.index = 0x1400, .sub = 1, .type = DataType::u32, .value = 0x80000205});
    add({.index = 0x1400, .sub = 2, .type = DataType::u8, .value = 255});
    add({.index = 0x1400, .sub = 5, .type = DataType::u16, .value = 0});
    add({.index = 0x1600, .sub = 0, .type = DataType::u8, .value = 0, .max = 8});
    for (std::uint8_t sub = 1; sub <= 8; ++sub) add({.index = 0x1600, .sub = sub, .type = DataType::u32});
    add({.index = 0x6040, .sub = 0, .type = DataType::u16, .access = Access::wo, .pdo_mappable = true});
    add({.index = 0x6060, .sub = 0, .type = DataType::i8, .access = Access::rw});
    add({.index = 0x6071, .sub = 0, .type = DataType::i16, .access = Access::rw, .pdo_mappable = true});
    od.set_observer(this);
  }
  std::uint32_t validate_write(const ObjectEntry& entry, std::span<const std::uint8_t> value) noexcept override {
    const bool pdo_valid = (od.get_int(0x1400, 1).value_or(0) & kPdoCobIdInvalid) == 0;
    std::uint32_t new_value = 0;
    for (std::size_t i = 0; i < value.size(); ++i) new_value |= static_cast<std::uint32_t>(value[i]) << (8 * i);
    if (entry.index() == 0x1400 && entry.sub() == 1) {
      const bool stays_valid = (new_value & kPdoCobIdInvalid) == 0;
      if (pdo_valid && stays_valid && (new_value & 0x7FF) != (entry.as_int() & 0x7FF)) return kAbortInvalidValue;
      return 0;
    }
    if (entry.index() != 0x1600) return 0;
    if (pdo_valid) return kAbortDeviceState;
    if (entry.sub() != 0) return od.get_int(0x1600, 0) == 0 ? 0 : kAbortDeviceState;
    if (new_value == 0) return 0;
    std::array<std::uint32_t, 8> raw{};
    for (std::uint8_t sub = 1; sub <= new_value; ++sub) {
      raw[sub - 1] = static_cast<std::uint32_t>(od.get_int(0x1600, sub).value_or(0));
    }
    return map_from_dictionary({raw.data(), new_value}, PdoDirection::receive, od, mapping);
  }
  void on_written(const ObjectEntry&) noexcept override {}

  ObjectDictionary od;
  PdoMapping mapping;
};

TEST(Pdo, ConfigureThroughSdoThenExchange) {
  RpdoSlave slave;
  SdoServer server(slave.od, kPdoNode);
  SdoClient client;
  PdoConfiguration config;
  config.pdo_number = 1;
  config.can_id = cob_id(FrameKind::rpdo, kPdoNode, 1);
  config.transmission_type = 1;
  config.event_timer_ms = 20;
  ASSERT_TRUE(config.mapping.add(0x6040, 0, 16, false).is_ok());
  ASSERT_TRUE(config.mapping.add(0x6071, 0, 16, true).is_ok());
  core::FixedVector<SdoWrite, kMaxPdoConfigurationWrites> writes;
  ASSERT_TRUE(pdo_configuration_writes(config, writes).is_ok());
  std::int64_t now = 0;
  for (const SdoWrite& write : writes) {
    ASSERT_TRUE(client.start_download(kPdoNode, write.index, write.sub, write.bytes(), now).is_ok());
    for (int i = 0; i < 4 && client.busy(); ++i) {
      if (auto tx = client.next_tx()) server.on_frame(*tx, now);
      if (auto tx = server.next_tx()) client.on_frame(*tx, now);
    }
    ASSERT_EQ(client.status(), SdoStatus::done)
        << std::hex << write.index << ":" << int{write.sub} << " " << describe_sdo_abort(client.abort_code());
  }
  EXPECT_EQ(slave.od.get_int(0x1400, 1), 0x40000205);
  EXPECT_EQ(slave.od.get_int(0x1400, 5), 20);
  ASSERT_EQ(slave.mapping.size(), 2U);
  EXPECT_TRUE(slave.mapping[1].is_signed);

  // The master packs an RPDO, the slave stores it into its dictionary.
  can_frame rpdo = make_frame(config.can_id, {});
  const std::int64_t values[2] = {0x000F, -321};
  ASSERT_TRUE(config.mapping.pack(values, rpdo).is_ok());
  ASSERT_TRUE(unpack_to_dictionary(slave.mapping, rpdo, slave.od).is_ok());
  EXPECT_EQ(slave.od.get_int(0x6040, 0), 0x000F);
  EXPECT_EQ(slave.od.get_int(0x6071, 0), -321);
  can_frame back{};
  ASSERT_TRUE(pack_from_dictionary(slave.mapping, slave.od, back).is_ok());
  EXPECT_EQ(std::memcmp(back.data, rpdo.data, 4), 0);

  // While the PDO is valid its mapping may not change, and the id may not move.
  const std::uint8_t zero[1] = {0};
  ASSERT_TRUE(client.start_download(kPdoNode, 0x1600, 0, zero, now).is_ok());
  server.on_frame(*client.next_tx(), now);
  client.on_frame(*server.next_tx(), now);
  EXPECT_EQ(client.abort_code(), kAbortDeviceState);
  const std::uint8_t other_id[4] = {0x06, 0x02, 0x00, 0x40};
  ASSERT_TRUE(client.start_download(kPdoNode, 0x1400, 1, other_id, now).is_ok());
  server.on_frame(*client.next_tx(), now);
  client.on_frame(*server.next_tx(), now);
  EXPECT_EQ(client.abort_code(), kAbortInvalidValue);
}

TEST(Pdo, MapFromDictionaryChecks) {
  RpdoSlave slave;
  PdoMapping mapping;
  const std::uint32_t ok[2] = {0x60400010, 0x60710010};
  EXPECT_EQ(map_from_dictionary(ok, PdoDirection::receive, slave.od, mapping), 0U);
  EXPECT_EQ(mapping.size(), 2U);
  const std::uint32_t missing[1] = {0x60720010};
  EXPECT_EQ(map_from_dictionary(missing, PdoDirection::receive, slave.od, mapping), kAbortNoObject);
  EXPECT_EQ(mapping.size(), 0U);
  const std::uint32_t missing_sub[1] = {0x60400110};
  EXPECT_EQ(map_from_dictionary(missing_sub, PdoDirection::receive, slave.od, mapping), kAbortNoSubIndex);
  const std::uint32_t not_mappable[1] = {0x60600008};
  EXPECT_EQ(map_from_dictionary(not_mappable, PdoDirection::receive, slave.od, mapping), kAbortNotMappable);
  const std::uint32_t wrong_length[1] = {0x60400008};
  EXPECT_EQ(map_from_dictionary(wrong_length, PdoDirection::receive, slave.od, mapping), kAbortNotMappable);
  const std::uint32_t write_only_in_tpdo[1] = {0x60400010};
  EXPECT_EQ(map_from_dictionary(write_only_in_tpdo, PdoDirection::transmit, slave.od, mapping), kAbortReadWriteOnly);
  std::array<std::uint32_t, 5> too_long{};
  too_long.fill(0x60400010);
  EXPECT_EQ(map_from_dictionary(too_long, PdoDirection::receive, slave.od, mapping), kAbortPdoLength);  // 80 bits
  std::array<std::uint32_t, 9> too_many{};
  too_many.fill(0x60400010);
  EXPECT_EQ(map_from_dictionary(too_many, PdoDirection::receive, slave.od, mapping), kAbortPdoLength);
}

}  // namespace
}  // namespace trainer::hal::canopen
