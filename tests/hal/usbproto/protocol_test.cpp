// The USB haptic interface protocol (hal/usbproto, docs/usb-protocol.md): byte-exact layouts
// on known vectors (little-endian), round trips at every channel count, every refusal of the
// decoders and encoders, CRC-8 against its published check value, sequence and count
// arithmetic across wrap-around, and no heap in encode/decode.
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/hal_usbproto/protocol.hpp"

namespace trainer::hal::usbproto {
namespace {

using Bytes = std::array<std::uint8_t, kReportSize>;

InReport sample_in(std::uint8_t channels) {
  InReport report;
  report.sequence = 0x1234;
  report.out_sequence_applied = 0xABCD;
  report.device_time_us = 0x89ABCDEFU;
  report.status = kStatusEnabled | kStatusCurrentLimited;
  report.buttons = 0x8001;
  report.channel_count = channels;
  for (std::size_t i = 0; i < channels; ++i) {
    const auto magnitude = static_cast<std::int32_t>(1000 * (i + 1) + 7);
    report.counts[i] = (i % 2 == 0) ? magnitude : -magnitude;
  }
  return report;
}

OutReport sample_out(std::uint8_t channels) {
  OutReport report;
  report.sequence = 0xFFFE;
  report.flags = kOutFlagEnable;
  report.channel_count = channels;
  for (std::size_t i = 0; i < channels; ++i) {
    const auto magnitude = static_cast<std::int16_t>(100 * (i + 1) + 3);
    report.current_ma[i] = (i % 2 == 0) ? magnitude : static_cast<std::int16_t>(-magnitude);
  }
  return report;
}

void expect_same(const InReport& a, const InReport& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.out_sequence_applied, b.out_sequence_applied);
  EXPECT_EQ(a.device_time_us, b.device_time_us);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.buttons, b.buttons);
  EXPECT_EQ(a.channel_count, b.channel_count);
  for (std::size_t i = 0; i < kMaxChannels; ++i) EXPECT_EQ(a.counts[i], b.counts[i]) << i;
}

void expect_same(const OutReport& a, const OutReport& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.flags, b.flags);
  EXPECT_EQ(a.channel_count, b.channel_count);
  for (std::size_t i = 0; i < kMaxChannels; ++i) EXPECT_EQ(a.current_ma[i], b.current_ma[i]) << i;
}

// Rewrites the CRC after a test changed a byte, so that the check under test is reached.
void reseal(std::span<std::uint8_t> bytes) {
  bytes.back() = crc8(bytes.first(bytes.size() - 1));
}

// --- CRC -----------------------------------------------------------------------------------

TEST(UsbCrc8, PublishedCheckValue) {
  // CRC-8/SMBUS check value (reveng catalogue): "123456789" -> 0xF4.
  const std::array<std::uint8_t, 9> text{'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(crc8(text), 0xF4);
  EXPECT_EQ(crc8(std::span<const std::uint8_t>{}), 0x00);
}

// --- known byte vectors (endianness, offsets) -----------------------------------------------

TEST(UsbInReport, KnownBytes) {
  InReport report;
  report.sequence = 0x0102;
  report.out_sequence_applied = 0x0304;
  report.device_time_us = 0x05060708U;
  report.status = 0x090A;
  report.buttons = 0x0B0C;
  report.channel_count = 3;
  report.counts[0] = 0x0D0E0F;   // positive
  report.counts[1] = -2;         // 0xFFFFFE
  report.counts[2] = kMinWireCount;  // 0x800000
  Bytes bytes{};
  ASSERT_EQ(encode(report, bytes), kReportSize);
  const std::array<std::uint8_t, 24> head{0x49, 0x01, 0x03, 0x02, 0x01, 0x04, 0x03, 0x08,
                                          0x07, 0x06, 0x05, 0x0A, 0x09, 0x0C, 0x0B, 0x0F,
                                          0x0E, 0x0D, 0xFE, 0xFF, 0xFF, 0x00, 0x00, 0x80};
  EXPECT_TRUE(std::equal(head.begin(), head.end(), bytes.begin()));
  EXPECT_TRUE(std::all_of(bytes.begin() + 24, bytes.end() - 1, [](std::uint8_t b) { return b == 0; }));
  EXPECT_EQ(bytes[63], crc8(std::span<const std::uint8_t>(bytes).first(63)));
  InReport decoded;
  ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok);
  expect_same(decoded, report);
}

TEST(UsbOutReport, KnownBytes) {
  OutReport report;
  report.sequence = 0xA1B2;
  report.flags = kOutFlagEnable | kOutFlagClearWatchdog;
  report.channel_count = 2;
  report.current_ma[0] = 0x1234;
  report.current_ma[1] = -1;
  Bytes bytes{};
  ASSERT_EQ(encode(report, bytes), kReportSize);
  const std::array<std::uint8_t, 10> head{0x4F, 0x01, 0x02, 0x03, 0xB2, 0xA1, 0x34, 0x12, 0xFF, 0xFF};
  EXPECT_TRUE(std::equal(head.begin(), head.end(), bytes.begin()));
  EXPECT_TRUE(std::all_of(bytes.begin() + 10, bytes.end() - 1, [](std::uint8_t b) { return b == 0; }));
  OutReport decoded;
  ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok);
  expect_same(decoded, report);
}

TEST(UsbIdentity, KnownBytes) {
  const Identity identity{.protocol_version = kProtocolVersion,
                          .firmware_version = 0x0102,
                          .channel_count = 10,
                          .watchdog_ms = 20,
                          .frame_interval_us = 1000,
                          .max_current_ma = 3000};
  std::array<std::uint8_t, kIdentitySize> bytes{};
  ASSERT_EQ(encode(identity, bytes), kIdentitySize);
  const std::array<std::uint8_t, 15> head{0x44, 0x01, 0x0A, 0x00, 0x02, 0x01, 0x14, 0x00,
                                          0xE8, 0x03, 0x00, 0x00, 0xB8, 0x0B, 0x00};
  EXPECT_TRUE(std::equal(head.begin(), head.end(), bytes.begin()));
  Identity decoded;
  ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok);
  EXPECT_EQ(decoded.protocol_version, kProtocolVersion);
  EXPECT_EQ(decoded.firmware_version, 0x0102);
  EXPECT_EQ(decoded.channel_count, 10);
  EXPECT_EQ(decoded.watchdog_ms, 20);
  EXPECT_EQ(decoded.frame_interval_us, 1000U);
  EXPECT_EQ(decoded.max_current_ma, 3000);
}

// --- round trips at every channel count -----------------------------------------------------

TEST(UsbInReport, RoundTripEveryChannelCount) {
  for (std::uint8_t channels = 0; channels <= kMaxChannels; ++channels) {
    const InReport report = sample_in(channels);
    Bytes bytes{};
    ASSERT_EQ(encode(report, bytes), kReportSize) << int{channels};
    InReport decoded;
    decoded.counts[kMaxChannels - 1] = 99;  // must be overwritten with 0
    ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok) << int{channels};
    expect_same(decoded, report);
  }
}

TEST(UsbOutReport, RoundTripEveryChannelCount) {
  for (std::uint8_t channels = 0; channels <= kMaxChannels; ++channels) {
    const OutReport report = sample_out(channels);
    Bytes bytes{};
    ASSERT_EQ(encode(report, bytes), kReportSize) << int{channels};
    OutReport decoded;
    decoded.current_ma[kMaxChannels - 1] = 99;
    ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok) << int{channels};
    expect_same(decoded, report);
  }
}

TEST(UsbInReport, ExtremeValuesRoundTrip) {
  InReport report;
  report.sequence = 0xFFFF;
  report.out_sequence_applied = 0xFFFF;
  report.device_time_us = 0xFFFFFFFFU;
  report.status = 0xFFFF;  // unknown status bits are carried, not refused
  report.buttons = 0xFFFF;
  report.channel_count = kMaxChannels;
  for (std::size_t i = 0; i < kMaxChannels; ++i) report.counts[i] = (i % 2 == 0) ? kMaxWireCount : kMinWireCount;
  Bytes bytes{};
  ASSERT_EQ(encode(report, bytes), kReportSize);
  InReport decoded;
  ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok);
  expect_same(decoded, report);
}

TEST(UsbOutReport, ExtremeCurrentsRoundTrip) {
  OutReport report;
  report.channel_count = kMaxChannels;
  for (std::size_t i = 0; i < kMaxChannels; ++i) report.current_ma[i] = (i % 2 == 0) ? INT16_MAX : INT16_MIN;
  Bytes bytes{};
  ASSERT_EQ(encode(report, bytes), kReportSize);
  OutReport decoded;
  ASSERT_EQ(decode(bytes, decoded), DecodeStatus::ok);
  expect_same(decoded, report);
}

// --- encoder refusals ------------------------------------------------------------------------

TEST(UsbEncode, RefusesWhatCannotBeSent) {
  Bytes bytes{};
  InReport in = sample_in(4);
  in.channel_count = kMaxChannels + 1;
  EXPECT_EQ(encode(in, bytes), 0U);
  in = sample_in(4);
  in.counts[2] = kMaxWireCount + 1;
  EXPECT_EQ(encode(in, bytes), 0U);
  in = sample_in(4);
  in.counts[3] = kMinWireCount - 1;
  EXPECT_EQ(encode(in, bytes), 0U);
  in = sample_in(4);
  in.counts[4] = 1;  // unused slot
  EXPECT_EQ(encode(in, bytes), 0U);

  OutReport out = sample_out(4);
  out.channel_count = kMaxChannels + 1;
  EXPECT_EQ(encode(out, bytes), 0U);
  out = sample_out(4);
  out.flags = 0x04;  // undefined flag
  EXPECT_EQ(encode(out, bytes), 0U);
  out = sample_out(4);
  out.current_ma[kMaxChannels - 1] = 5;  // unused slot
  EXPECT_EQ(encode(out, bytes), 0U);

  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  Identity identity{.channel_count = kMaxChannels + 1};
  EXPECT_EQ(encode(identity, id_bytes), 0U);
  identity = Identity{.protocol_version = 2, .channel_count = 1};
  EXPECT_EQ(encode(identity, id_bytes), 0U);
}

// --- decoder refusals (in the documented order) ----------------------------------------------

TEST(UsbDecode, WrongLength) {
  Bytes bytes{};
  ASSERT_EQ(encode(sample_in(3), bytes), kReportSize);
  InReport in;
  const std::span<const std::uint8_t> all(bytes);
  EXPECT_EQ(decode(all.first(63), in), DecodeStatus::wrong_length);
  EXPECT_EQ(decode(all.first(0), in), DecodeStatus::wrong_length);
  std::array<std::uint8_t, 65> longer{};
  std::copy(bytes.begin(), bytes.end(), longer.begin());
  EXPECT_EQ(decode(longer, in), DecodeStatus::wrong_length);
  OutReport out;
  EXPECT_EQ(decode(all.first(1), out), DecodeStatus::wrong_length);
  Identity identity;
  EXPECT_EQ(decode(all, identity), DecodeStatus::wrong_length);  // 64 bytes, not 16
}

TEST(UsbDecode, BadMagicRefusesTheOtherDirection) {
  Bytes in_bytes{};
  Bytes out_bytes{};
  ASSERT_EQ(encode(sample_in(3), in_bytes), kReportSize);
  ASSERT_EQ(encode(sample_out(3), out_bytes), kReportSize);
  InReport in;
  OutReport out;
  EXPECT_EQ(decode(out_bytes, in), DecodeStatus::bad_magic);
  EXPECT_EQ(decode(in_bytes, out), DecodeStatus::bad_magic);
  Bytes zeros{};
  EXPECT_EQ(decode(zeros, in), DecodeStatus::bad_magic);
  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  std::copy_n(in_bytes.begin(), kIdentitySize, id_bytes.begin());
  Identity identity;
  EXPECT_EQ(decode(id_bytes, identity), DecodeStatus::bad_magic);
}

TEST(UsbDecode, BadVersion) {
  Bytes bytes{};
  ASSERT_EQ(encode(sample_in(3), bytes), kReportSize);
  bytes[1] = 2;
  reseal(bytes);
  InReport in;
  EXPECT_EQ(decode(bytes, in), DecodeStatus::bad_version);
  ASSERT_EQ(encode(sample_out(3), bytes), kReportSize);
  bytes[1] = 0;
  reseal(bytes);
  OutReport out;
  EXPECT_EQ(decode(bytes, out), DecodeStatus::bad_version);
  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  ASSERT_EQ(encode(Identity{.channel_count = 2}, id_bytes), kIdentitySize);
  id_bytes[1] = 9;
  reseal(id_bytes);
  Identity identity;
  EXPECT_EQ(decode(id_bytes, identity), DecodeStatus::bad_version);
}

TEST(UsbDecode, BadChecksumOnEverySingleBitFlip) {
  Bytes original{};
  ASSERT_EQ(encode(sample_in(kMaxChannels), original), kReportSize);
  // Every single-bit error past the magic and version bytes is caught by the CRC (CRC-8
  // detects all single-bit errors); flips in bytes 0 and 1 hit the magic/version checks.
  for (std::size_t byte = 2; byte < kReportSize; ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      Bytes bytes = original;
      bytes[byte] = static_cast<std::uint8_t>(bytes[byte] ^ (1U << bit));
      InReport in;
      in.sequence = 7;
      EXPECT_EQ(decode(bytes, in), DecodeStatus::bad_checksum) << byte << ":" << bit;
      EXPECT_EQ(in.sequence, 7) << "out written on refusal";
    }
  }
  ASSERT_EQ(encode(sample_out(5), original), kReportSize);
  Bytes bytes = original;
  bytes[10] ^= 0x40U;
  OutReport out;
  EXPECT_EQ(decode(bytes, out), DecodeStatus::bad_checksum);
  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  ASSERT_EQ(encode(Identity{.channel_count = 2, .watchdog_ms = 20}, id_bytes), kIdentitySize);
  id_bytes[6] ^= 0x01U;
  Identity identity;
  EXPECT_EQ(decode(id_bytes, identity), DecodeStatus::bad_checksum);
}

TEST(UsbDecode, BadChannelCount) {
  Bytes bytes{};
  ASSERT_EQ(encode(sample_in(kMaxChannels), bytes), kReportSize);
  bytes[2] = kMaxChannels + 1;
  reseal(bytes);
  InReport in;
  EXPECT_EQ(decode(bytes, in), DecodeStatus::bad_channel_count);
  bytes[2] = 0xFF;
  reseal(bytes);
  EXPECT_EQ(decode(bytes, in), DecodeStatus::bad_channel_count);
  ASSERT_EQ(encode(sample_out(kMaxChannels), bytes), kReportSize);
  bytes[2] = kMaxChannels + 1;
  reseal(bytes);
  OutReport out;
  EXPECT_EQ(decode(bytes, out), DecodeStatus::bad_channel_count);
  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  ASSERT_EQ(encode(Identity{.channel_count = kMaxChannels}, id_bytes), kIdentitySize);
  id_bytes[2] = kMaxChannels + 1;
  reseal(id_bytes);
  Identity identity;
  EXPECT_EQ(decode(id_bytes, identity), DecodeStatus::bad_channel_count);
}

TEST(UsbDecode, ReservedNotZero) {
  // A non-zero byte in an unused channel slot: a report with fewer channels than its data.
  for (std::uint8_t channels = 0; channels < kMaxChannels; ++channels) {
    Bytes bytes{};
    ASSERT_EQ(encode(sample_in(channels), bytes), kReportSize);
    bytes[15 + 3 * std::size_t{channels}] = 1;  // first byte of the first unused count
    reseal(bytes);
    InReport in;
    EXPECT_EQ(decode(bytes, in), DecodeStatus::reserved_not_zero) << int{channels};
    bytes[15 + 3 * std::size_t{channels}] = 0;
    bytes[62] = 0x80;  // last byte before the CRC
    reseal(bytes);
    EXPECT_EQ(decode(bytes, in), DecodeStatus::reserved_not_zero) << int{channels};

    ASSERT_EQ(encode(sample_out(channels), bytes), kReportSize);
    bytes[6 + 2 * std::size_t{channels} + 1] = 1;
    reseal(bytes);
    OutReport out;
    EXPECT_EQ(decode(bytes, out), DecodeStatus::reserved_not_zero) << int{channels};
  }
  Bytes bytes{};
  ASSERT_EQ(encode(sample_out(kMaxChannels), bytes), kReportSize);
  bytes[62] = 1;  // reserved tail after the currents
  reseal(bytes);
  OutReport out;
  EXPECT_EQ(decode(bytes, out), DecodeStatus::reserved_not_zero);
  ASSERT_EQ(encode(sample_out(kMaxChannels), bytes), kReportSize);
  bytes[3] = kOutFlagEnable | 0x80;  // undefined flag bit
  reseal(bytes);
  EXPECT_EQ(decode(bytes, out), DecodeStatus::reserved_not_zero);
  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  ASSERT_EQ(encode(Identity{.channel_count = 2}, id_bytes), kIdentitySize);
  id_bytes[3] = 1;
  reseal(id_bytes);
  Identity identity;
  EXPECT_EQ(decode(id_bytes, identity), DecodeStatus::reserved_not_zero);
  ASSERT_EQ(encode(Identity{.channel_count = 2}, id_bytes), kIdentitySize);
  id_bytes[14] = 1;
  reseal(id_bytes);
  EXPECT_EQ(decode(id_bytes, identity), DecodeStatus::reserved_not_zero);
}

TEST(UsbDecode, StatusNames) {
  EXPECT_STREQ(to_string(DecodeStatus::ok), "ok");
  EXPECT_STREQ(to_string(DecodeStatus::wrong_length), "wrong length");
  EXPECT_STREQ(to_string(DecodeStatus::bad_magic), "bad magic byte");
  EXPECT_STREQ(to_string(DecodeStatus::bad_version), "unsupported protocol version");
  EXPECT_STREQ(to_string(DecodeStatus::bad_checksum), "CRC-8 mismatch");
  EXPECT_STREQ(to_string(DecodeStatus::bad_channel_count), "channel count above 16");
  EXPECT_STREQ(to_string(DecodeStatus::reserved_not_zero),
               "reserved byte, flag or unused channel not zero");
}

// --- sequences and counts --------------------------------------------------------------------

TEST(UsbSequence, DistanceAcrossWrap) {
  EXPECT_EQ(sequence_distance(5, 5), 0);
  EXPECT_EQ(sequence_distance(6, 5), 1);
  EXPECT_EQ(sequence_distance(0, 0xFFFF), 1);
  EXPECT_EQ(sequence_distance(2, 0xFFFE), 4);
  EXPECT_EQ(sequence_distance(0xFFFE, 2), 0xFFFC);  // "behind" reads as almost a full wrap
}

TEST(UsbCounts, WireCountIsModulo24Bits) {
  EXPECT_EQ(wire_count(0), 0);
  EXPECT_EQ(wire_count(-1), -1);
  EXPECT_EQ(wire_count(kMaxWireCount), kMaxWireCount);
  EXPECT_EQ(wire_count(kMinWireCount), kMinWireCount);
  EXPECT_EQ(wire_count(std::int64_t{kMaxWireCount} + 1), kMinWireCount);
  EXPECT_EQ(wire_count(std::int64_t{1} << 24), 0);
  EXPECT_EQ(wire_count((std::int64_t{1} << 40) + 5), 5);
  EXPECT_EQ(wire_count(-(std::int64_t{1} << 24) - 3), -3);
}

TEST(UsbCounts, ExtendFollowsACountPastTheWireRange) {
  // A count that runs from -3 * 2^24 to +3 * 2^24 in steps just under 2^23 is recovered
  // exactly from its wire values.
  std::int64_t host = -3 * (std::int64_t{1} << 24);
  for (std::int64_t truth = host; truth < 3 * (std::int64_t{1} << 24); truth += 8'000'001) {
    host = extend_count(host, wire_count(truth));
    ASSERT_EQ(host, truth);
  }
  for (std::int64_t truth = host; truth > -3 * (std::int64_t{1} << 24); truth -= 8'000'001) {
    host = extend_count(host, wire_count(truth));
    ASSERT_EQ(host, truth);
  }
  EXPECT_EQ(extend_count(100, 100), 100);
  EXPECT_EQ(extend_count(kMaxWireCount, kMinWireCount), std::int64_t{kMaxWireCount} + 1);
}

// --- an independent encoder ----------------------------------------------------------------

std::vector<std::uint8_t> read_seed(const char* name) {
  const std::string path = std::string(TRAINER_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_usb_in_report/" + name;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return {};
  std::vector<std::uint8_t> bytes(128);
  bytes.resize(std::fread(bytes.data(), 1, bytes.size(), file));
  std::fclose(file);
  return bytes;
}

// The fuzz seed corpus is written by tests/fuzz/make_seed_corpus.py, a Python encoder written
// from docs/usb-protocol.md: the C++ decoder must read its reports field for field.
TEST(UsbSeedCorpus, PythonEncodedReportsDecode) {
  const std::vector<std::uint8_t> in_bytes = read_seed("in_10_channels");
  ASSERT_EQ(in_bytes.size(), kReportSize);
  InReport in;
  ASSERT_EQ(decode(in_bytes, in), DecodeStatus::ok);
  EXPECT_EQ(in.sequence, 7);
  EXPECT_EQ(in.out_sequence_applied, 6);
  EXPECT_EQ(in.device_time_us, 7000U);
  EXPECT_EQ(in.status, kStatusEnabled);
  EXPECT_EQ(in.buttons, 1);
  ASSERT_EQ(in.channel_count, 10);
  const std::int32_t counts[10] = {0, 1, -1, 4096, -4096, kMaxWireCount, kMinWireCount, 12, 13, 14};
  for (std::size_t i = 0; i < 10; ++i) EXPECT_EQ(in.counts[i], counts[i]) << i;

  const std::vector<std::uint8_t> out_bytes = read_seed("out_10_channels");
  OutReport out;
  ASSERT_EQ(decode(out_bytes, out), DecodeStatus::ok);
  EXPECT_EQ(out.sequence, 9);
  EXPECT_EQ(out.flags, kOutFlagEnable);
  ASSERT_EQ(out.channel_count, 10);
  EXPECT_EQ(out.current_ma[3], INT16_MAX);
  EXPECT_EQ(out.current_ma[4], INT16_MIN);

  const std::vector<std::uint8_t> id_bytes = read_seed("identity");
  Identity identity;
  ASSERT_EQ(decode(id_bytes, identity), DecodeStatus::ok);
  EXPECT_EQ(identity.channel_count, 10);
  EXPECT_EQ(identity.firmware_version, 0x0100);
  EXPECT_EQ(identity.watchdog_ms, 20);
  EXPECT_EQ(identity.frame_interval_us, 1000U);
  EXPECT_EQ(identity.max_current_ma, 3000);

  for (const char* name : {"in_16_channels", "in_tripped_empty"}) {
    const std::vector<std::uint8_t> bytes = read_seed(name);
    EXPECT_EQ(decode(bytes, in), DecodeStatus::ok) << name;
  }
}

// --- no heap ---------------------------------------------------------------------------------

TEST(UsbNoHeap, EncodeDecodeAllocateNothing) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  const InReport in = sample_in(10);
  const OutReport out = sample_out(10);
  Bytes bytes{};
  std::array<std::uint8_t, kIdentitySize> id_bytes{};
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  std::size_t ok = 0;
  for (int i = 0; i < 1000; ++i) {
    InReport in_decoded;
    OutReport out_decoded;
    Identity identity;
    ok += encode(in, bytes) == kReportSize && decode(bytes, in_decoded) == DecodeStatus::ok;
    ok += encode(out, bytes) == kReportSize && decode(bytes, out_decoded) == DecodeStatus::ok;
    ok += encode(Identity{.channel_count = 10}, id_bytes) == kIdentitySize &&
          decode(id_bytes, identity) == DecodeStatus::ok;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_EQ(ok, 3000U);
}

}  // namespace
}  // namespace trainer::hal::usbproto
