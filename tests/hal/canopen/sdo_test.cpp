// SDO client and server (CiA 301 v4.2, 7.2.4): byte-exact frames for every command
// specifier, segmented transfers with toggle alternation, end bit and unused-byte count,
// aborts (toggle, unknown object, timeout, access, length, range), abort texts, and the
// client against the server back to back for randomised sizes 0..300 bytes.
#include <algorithm>
#include <array>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/sdo.hpp"
#include "trainer/hal_canopen/sdo_client.hpp"
#include "trainer/hal_canopen/sdo_server.hpp"

namespace trainer::hal::canopen {
namespace {

constexpr std::uint8_t kSdoNode = 5;
constexpr std::int64_t kSdoMs = 1'000'000;

using Bytes = std::array<std::uint8_t, 8>;

Bytes bytes_of(const can_frame& frame) {
  Bytes bytes{};
  std::copy_n(frame.data, 8, bytes.begin());
  return bytes;
}

can_frame sdo(canid_t id, Bytes data) {
  can_frame frame{};
  frame.can_id = id;
  frame.len = 8;
  std::copy(data.begin(), data.end(), frame.data);
  return frame;
}
can_frame response(Bytes data) { return sdo(0x580 + kSdoNode, data); }
can_frame request(Bytes data) { return sdo(0x600 + kSdoNode, data); }

// Takes the client's pending frame, checks its id and returns its bytes.
Bytes take_request(SdoClient& client) {
  const auto frame = client.next_tx();
  EXPECT_TRUE(frame.has_value());
  if (!frame) return {};
  EXPECT_EQ(frame->can_id, 0x600U + kSdoNode);
  EXPECT_EQ(frame->len, 8);
  return bytes_of(*frame);
}
Bytes take_response(SdoServer& server) {
  const auto frame = server.next_tx();
  EXPECT_TRUE(frame.has_value());
  if (!frame) return {};
  EXPECT_EQ(frame->can_id, 0x580U + kSdoNode);
  EXPECT_EQ(frame->len, 8);
  return bytes_of(*frame);
}

// --- client frames -----------------------------------------------------------------------

TEST(SdoClient, ExpeditedDownloadCommandBytes) {
  struct Case {
    std::size_t size;
    std::uint8_t command;
  };
  for (const Case c : {Case{1, 0x2F}, Case{2, 0x2B}, Case{3, 0x27}, Case{4, 0x23}}) {
    SdoClient client;
    const std::uint8_t data[4] = {0x0A, 0x0B, 0x0C, 0x0D};
    ASSERT_TRUE(client.start_download(kSdoNode, 0x6060, 0, {data, c.size}, 0).is_ok());
    Bytes expected = {c.command, 0x60, 0x60, 0x00, 0, 0, 0, 0};
    std::copy_n(data, c.size, expected.begin() + 4);
    EXPECT_EQ(take_request(client), expected) << c.size;
    EXPECT_FALSE(client.next_tx().has_value());  // given once
    EXPECT_EQ(client.status(), SdoStatus::busy);
    EXPECT_TRUE(client.on_frame(response({0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0}), 1));
    EXPECT_EQ(client.status(), SdoStatus::done);
    EXPECT_EQ(client.transferred_bytes(), c.size);
    EXPECT_FALSE(client.next_tx().has_value());
  }
}

TEST(SdoClient, ExpeditedUploadResponses) {
  struct Case {
    std::uint8_t command;
    std::size_t size;
  };
  for (const Case c : {Case{0x4F, 1}, Case{0x4B, 2}, Case{0x47, 3}, Case{0x43, 4}}) {
    SdoClient client;
    std::array<std::uint8_t, 4> buffer{};
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x6041, 0, buffer, 0).is_ok());
    EXPECT_EQ(take_request(client), (Bytes{0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0}));
    client.on_frame(response({c.command, 0x41, 0x60, 0x00, 0x37, 0x02, 0x11, 0x22}), 1);
    EXPECT_EQ(client.status(), SdoStatus::done);
    EXPECT_EQ(client.transferred_bytes(), c.size);
    EXPECT_EQ(client.indicated_size(), c.size);
    EXPECT_EQ(buffer[0], 0x37);
    if (c.size >= 2) {
      EXPECT_EQ(buffer[1], 0x02);
    }
    if (c.size < 4) {
      EXPECT_EQ(buffer[c.size], 0) << "no byte beyond the indicated size";
    }
  }
}

TEST(SdoClient, SegmentedDownloadTogglesAndEnds) {
  SdoClient client;
  const std::uint8_t data[10] = {'0', '1', '2', '3', '4', '5', '6', '7', '8', '9'};
  ASSERT_TRUE(client.start_download(kSdoNode, 0x1008, 0, data, 0).is_ok());
  // Initiate, size indicated: 0x21, size 10 in bytes 4..7.
  EXPECT_EQ(take_request(client), (Bytes{0x21, 0x08, 0x10, 0x00, 10, 0, 0, 0}));
  client.on_frame(response({0x60, 0x08, 0x10, 0x00, 0, 0, 0, 0}), 1);
  // Segment 1: t=0, 7 bytes, not last.
  EXPECT_EQ(take_request(client), (Bytes{0x00, '0', '1', '2', '3', '4', '5', '6'}));
  client.on_frame(response({0x20, 0, 0, 0, 0, 0, 0, 0}), 2);
  EXPECT_EQ(client.transferred_bytes(), 7U);
  // Segment 2: t=1, 3 bytes (n = 4 unused), last: 0x10 | 4 << 1 | 1 = 0x19.
  EXPECT_EQ(take_request(client), (Bytes{0x19, '7', '8', '9', 0, 0, 0, 0}));
  EXPECT_EQ(client.status(), SdoStatus::busy);
  client.on_frame(response({0x30, 0, 0, 0, 0, 0, 0, 0}), 3);
  EXPECT_EQ(client.status(), SdoStatus::done);
  EXPECT_EQ(client.transferred_bytes(), 10U);
}

TEST(SdoClient, ZeroBytesAreASegmentedTransferWithOneEmptySegment) {
  SdoClient client;
  ASSERT_TRUE(client.start_download(kSdoNode, 0x2000, 1, {}, 0).is_ok());
  EXPECT_EQ(take_request(client), (Bytes{0x21, 0x00, 0x20, 0x01, 0, 0, 0, 0}));
  client.on_frame(response({0x60, 0x00, 0x20, 0x01, 0, 0, 0, 0}), 1);
  EXPECT_EQ(take_request(client), (Bytes{0x0F, 0, 0, 0, 0, 0, 0, 0}));  // n = 7, c = 1
  client.on_frame(response({0x20, 0, 0, 0, 0, 0, 0, 0}), 2);
  EXPECT_EQ(client.status(), SdoStatus::done);
  EXPECT_EQ(client.transferred_bytes(), 0U);
}

TEST(SdoClient, SegmentedUpload) {
  SdoClient client;
  std::array<std::uint8_t, 32> buffer{};
  ASSERT_TRUE(client.start_upload(kSdoNode, 0x1008, 0, buffer, 0).is_ok());
  EXPECT_EQ(take_request(client), (Bytes{0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}));
  client.on_frame(response({0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0}), 1);
  EXPECT_EQ(client.indicated_size(), 12U);
  EXPECT_EQ(take_request(client), (Bytes{0x60, 0, 0, 0, 0, 0, 0, 0}));
  client.on_frame(response({0x00, 'h', 'a', 'p', 't', 'i', 'c', ' '}), 2);
  EXPECT_EQ(take_request(client), (Bytes{0x70, 0, 0, 0, 0, 0, 0, 0}));
  client.on_frame(response({0x15, 'd', 'r', 'i', 'v', 'e', 0, 0}), 3);  // t=1, n=2, c=1
  EXPECT_EQ(client.status(), SdoStatus::done);
  ASSERT_EQ(client.transferred_bytes(), 12U);
  EXPECT_EQ(std::string(buffer.begin(), buffer.begin() + 12), "haptic drive");
}

TEST(SdoClient, WrongToggleFromServerAborts) {
  SdoClient client;
  std::array<std::uint8_t, 32> buffer{};
  ASSERT_TRUE(client.start_upload(kSdoNode, 0x1008, 0, buffer, 0).is_ok());
  (void)client.next_tx();
  client.on_frame(response({0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0}), 1);
  (void)client.next_tx();
  client.on_frame(response({0x10, 'h', 'a', 'p', 't', 'i', 'c', ' '}), 2);  // t=1, expected 0
  EXPECT_EQ(client.status(), SdoStatus::aborted);
  EXPECT_EQ(client.abort_code(), kAbortToggleBit);
  EXPECT_FALSE(client.aborted_by_server());
  EXPECT_EQ(take_request(client), (Bytes{0x80, 0x08, 0x10, 0x00, 0x00, 0x00, 0x03, 0x05}));
}

TEST(SdoClient, DownloadSegmentWithWrongToggleAborts) {
  SdoClient client;
  const std::uint8_t data[9] = {};
  ASSERT_TRUE(client.start_download(kSdoNode, 0x2000, 0, data, 0).is_ok());
  (void)client.next_tx();
  client.on_frame(response({0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}), 1);
  (void)client.next_tx();
  client.on_frame(response({0x30, 0, 0, 0, 0, 0, 0, 0}), 2);  // t=1 answering t=0
  EXPECT_EQ(client.status(), SdoStatus::aborted);
  EXPECT_EQ(client.abort_code(), kAbortToggleBit);
}

TEST(SdoClient, ServerAbortIsDecoded) {
  SdoClient client;
  const std::uint8_t value[2] = {1, 2};
  ASSERT_TRUE(client.start_download(kSdoNode, 0x2000, 0, value, 0).is_ok());
  (void)client.next_tx();
  EXPECT_TRUE(client.on_frame(response({0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06}), 1));
  EXPECT_EQ(client.status(), SdoStatus::aborted);
  EXPECT_TRUE(client.aborted_by_server());
  EXPECT_EQ(client.abort_code(), kAbortNoObject);
  EXPECT_STREQ(describe_sdo_abort(client.abort_code()), "object does not exist in the object dictionary");
  EXPECT_FALSE(client.next_tx().has_value());  // an abort is never answered
}

TEST(SdoClient, TimeoutSendsAbort) {
  SdoClient client;
  client.set_response_timeout_ns(100 * kSdoMs);
  std::array<std::uint8_t, 4> buffer{};
  ASSERT_TRUE(client.start_upload(kSdoNode, 0x6041, 0, buffer, 1000 * kSdoMs).is_ok());
  (void)client.next_tx();
  client.on_time(1100 * kSdoMs);  // exactly the timeout: still waiting
  EXPECT_EQ(client.status(), SdoStatus::busy);
  client.on_time(1100 * kSdoMs + 1);
  EXPECT_EQ(client.status(), SdoStatus::timed_out);
  EXPECT_EQ(client.abort_code(), kAbortTimeout);
  EXPECT_EQ(take_request(client), (Bytes{0x80, 0x41, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05}));
  // A late response is not used.
  EXPECT_FALSE(client.on_frame(response({0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0}), 1200 * kSdoMs));
  EXPECT_EQ(client.status(), SdoStatus::timed_out);
}

TEST(SdoClient, ProtocolErrors) {
  std::array<std::uint8_t, 4> small{};
  {  // unexpected command specifier: a download response to an upload
    SdoClient client;
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x6041, 0, small, 0).is_ok());
    (void)client.next_tx();
    client.on_frame(response({0x60, 0x41, 0x60, 0x00, 0, 0, 0, 0}), 1);
    EXPECT_EQ(client.abort_code(), kAbortCommandSpecifier);
  }
  {  // response for another object
    SdoClient client;
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x6041, 0, small, 0).is_ok());
    (void)client.next_tx();
    client.on_frame(response({0x4B, 0x40, 0x60, 0x00, 0, 0, 0, 0}), 1);
    EXPECT_EQ(client.abort_code(), kAbortGeneral);
  }
  {  // value larger than the buffer
    SdoClient client;
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x1008, 0, small, 0).is_ok());
    (void)client.next_tx();
    client.on_frame(response({0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0}), 1);
    EXPECT_EQ(client.abort_code(), kAbortOutOfMemory);
  }
  {  // fewer bytes than announced
    SdoClient client;
    std::array<std::uint8_t, 32> buffer{};
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x1008, 0, buffer, 0).is_ok());
    (void)client.next_tx();
    client.on_frame(response({0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0}), 1);
    (void)client.next_tx();
    client.on_frame(response({0x0B, 'a', 'b', 'c', 0, 0, 0, 0}), 2);  // 3 bytes, last
    EXPECT_EQ(client.abort_code(), kAbortLengthMismatch);
  }
  {  // busy, bad node, frames for others, short frames
    SdoClient client;
    EXPECT_EQ(client.start_upload(0, 0x1000, 0, small, 0).code(), core::StatusCode::invalid_argument);
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x1000, 0, small, 0).is_ok());
    (void)client.next_tx();  // the initiate
    EXPECT_EQ(client.start_upload(kSdoNode, 0x1000, 0, small, 0).code(), core::StatusCode::not_ready);
    EXPECT_FALSE(client.on_frame(sdo(0x586, {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), 1));
    can_frame short_frame = response({0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4});
    short_frame.len = 7;
    EXPECT_FALSE(client.on_frame(short_frame, 1));
    EXPECT_EQ(client.ignored_frames(), 1U);
    EXPECT_EQ(client.status(), SdoStatus::busy);
    client.abort(kAbortGeneral);
    EXPECT_EQ(client.status(), SdoStatus::aborted);
    EXPECT_EQ(take_request(client), (Bytes{0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x08}));
  }
}

// --- object dictionary --------------------------------------------------------------------

class RecordingObserver final : public ObjectDictionaryObserver {
 public:
  std::uint32_t validate_write(const ObjectEntry& entry, std::span<const std::uint8_t> value) noexcept override {
    ++validated;
    // 0x6060 accepts only CST (10) and 0 in this test drive.
    if (entry.index() == 0x6060 && value[0] != 10 && value[0] != 0) return kAbortInvalidValue;
    return 0;
  }
  void on_written(const ObjectEntry& entry) noexcept override { last_written = entry.index(); }
  int validated = 0;
  std::uint16_t last_written = 0;
};

void build_dictionary(ObjectDictionary& od, std::span<std::uint8_t> domain) {
  ASSERT_TRUE(od.add({.index = 0x1000, .sub = 0, .type = DataType::u32, .access = Access::constant, .value = 0x20192}));
  ASSERT_TRUE(od.add({.index = 0x1017, .sub = 0, .type = DataType::u16, .access = Access::rw, .value = 0}));
  ASSERT_TRUE(od.add_string(0x1008, 0, Access::constant, "haptic drive"));
  ASSERT_TRUE(od.add({.index = 0x1018, .sub = 0, .type = DataType::u8, .access = Access::constant, .value = 4}));
  ASSERT_TRUE(od.add({.index = 0x1018, .sub = 1, .type = DataType::u32, .access = Access::ro, .value = 0x12345678}));
  ASSERT_TRUE(od.add({.index = 0x6040, .sub = 0, .type = DataType::u16, .access = Access::wo, .pdo_mappable = true}));
  ASSERT_TRUE(od.add({.index = 0x6041, .sub = 0, .type = DataType::u16, .access = Access::ro, .pdo_mappable = true}));
  ASSERT_TRUE(od.add({.index = 0x6060, .sub = 0, .type = DataType::i8, .access = Access::rw}));
  ASSERT_TRUE(od.add({.index = 0x6071, .sub = 0, .type = DataType::i16, .access = Access::rw,
                      .pdo_mappable = true, .min = -1000, .max = 1000}));
  ASSERT_TRUE(od.add_string(0x2001, 0, Access::rw, ""));
  ASSERT_TRUE(od.add_domain(0x2002, 0, Access::rw, domain, 0));
}

TEST(ObjectDictionary, SetupErrorsNameTheObject) {
  ObjectDictionary od;
  ASSERT_TRUE(od.add({.index = 0x6071, .sub = 0, .type = DataType::i16}));
  auto twice = od.add({.index = 0x6071, .sub = 0, .type = DataType::i16});
  ASSERT_FALSE(twice);
  EXPECT_EQ(twice.error().message, "object 0x6071:00: defined twice");
  auto too_big = od.add({.index = 0x6060, .sub = 0, .type = DataType::i8, .value = 200});
  ASSERT_FALSE(too_big);
  EXPECT_EQ(too_big.error().message, "object 0x6060:00: initial value 200 does not fit INTEGER8");
  EXPECT_FALSE(od.add({.index = 0x6072, .sub = 0, .type = DataType::u16, .min = 10, .max = 5}));
  EXPECT_FALSE(od.add({.index = 0x6073, .sub = 0, .type = DataType::visible_string}));
  EXPECT_FALSE(od.add_string(0x1008, 0, Access::constant, std::string(kMaxStringBytes + 1, 'x')));
  EXPECT_EQ(od.size(), 1U);
}

TEST(ObjectDictionary, RemoteAccessRulesAndLocalHelpers) {
  std::array<std::uint8_t, 512> domain{};
  ObjectDictionary od;
  build_dictionary(od, domain);
  RecordingObserver observer;
  od.set_observer(&observer);
  std::array<std::uint8_t, 64> out{};
  std::size_t size = 0;
  EXPECT_EQ(od.read(0x1018, 1, out, size), 0U);
  EXPECT_EQ(size, 4U);
  EXPECT_EQ(out[0], 0x78);
  EXPECT_EQ(od.read(0x1018, 5, out, size), kAbortNoSubIndex);
  EXPECT_EQ(od.read(0x1019, 0, out, size), kAbortNoObject);
  EXPECT_EQ(od.read(0x6040, 0, out, size), kAbortReadWriteOnly);
  const std::uint8_t two[2] = {0x0F, 0x00};
  EXPECT_EQ(od.write(0x6041, 0, two), kAbortWriteReadOnly);
  EXPECT_EQ(od.write(0x1000, 0, two), kAbortWriteReadOnly);  // const
  EXPECT_EQ(od.write(0x6040, 0, two), 0U);
  EXPECT_EQ(observer.last_written, 0x6040);
  const std::uint8_t one[1] = {1};
  const std::uint8_t four[4] = {1, 2, 3, 4};
  EXPECT_EQ(od.write(0x6040, 0, one), kAbortLengthTooLow);
  EXPECT_EQ(od.write(0x6040, 0, four), kAbortLengthTooHigh);
  // Range: 0x6071 in -1000..1000 (signed little-endian).
  const std::uint8_t plus_1001[2] = {0xE9, 0x03};
  const std::uint8_t minus_1001[2] = {0x17, 0xFC};
  const std::uint8_t minus_1000[2] = {0x18, 0xFC};
  EXPECT_EQ(od.write(0x6071, 0, plus_1001), kAbortValueTooHigh);
  EXPECT_EQ(od.write(0x6071, 0, minus_1001), kAbortValueTooLow);
  EXPECT_EQ(od.write(0x6071, 0, minus_1000), 0U);
  EXPECT_EQ(od.get_int(0x6071, 0), -1000);
  // The observer's verdict.
  const std::uint8_t mode_pp[1] = {1};
  const std::uint8_t mode_cst[1] = {10};
  EXPECT_EQ(od.write(0x6060, 0, mode_pp), kAbortInvalidValue);
  EXPECT_EQ(od.get_int(0x6060, 0), 0);
  EXPECT_EQ(od.write(0x6060, 0, mode_cst), 0U);
  EXPECT_EQ(od.get_int(0x6060, 0), 10);
  // Strings: any length up to the capacity.
  const std::string name = "left pitch";
  EXPECT_EQ(od.write(0x2001, 0, {reinterpret_cast<const std::uint8_t*>(name.data()), name.size()}), 0U);
  EXPECT_EQ(od.find(0x2001, 0)->as_string(), "left pitch");
  const std::string too_long(kMaxStringBytes + 1, 'x');
  EXPECT_EQ(od.write(0x2001, 0, {reinterpret_cast<const std::uint8_t*>(too_long.data()), too_long.size()}),
            kAbortLengthTooHigh);
  // Local typed access skips access rules and the observer.
  const int validated = observer.validated;
  EXPECT_TRUE(od.set<std::uint16_t>(0x6041, 0, 0x0237).is_ok());
  std::uint16_t statusword = 0;
  EXPECT_TRUE(od.get(0x6041, 0, statusword).is_ok());
  EXPECT_EQ(statusword, 0x0237);
  EXPECT_TRUE(od.set<std::int16_t>(0x6071, 0, -5).is_ok());
  std::int16_t torque = 0;
  EXPECT_TRUE(od.get(0x6071, 0, torque).is_ok());
  EXPECT_EQ(torque, -5);
  EXPECT_TRUE(od.set<std::uint16_t>(0x6071, 0, 0xFFFE).is_ok());  // bit pattern of -2
  EXPECT_EQ(od.get_int(0x6071, 0), -2);
  std::uint32_t wrong_size = 0;
  EXPECT_FALSE(od.get(0x6041, 0, wrong_size).is_ok());
  EXPECT_FALSE(od.set_int(0x6060, 0, 128).is_ok());  // does not fit i8
  EXPECT_EQ(observer.validated, validated);
}

// --- server frames ------------------------------------------------------------------------

struct ServerFixture {
  std::array<std::uint8_t, 512> domain{};
  ObjectDictionary od;
  SdoServer server{od, kSdoNode};
  ServerFixture() { build_dictionary(od, domain); }
  Bytes ask(Bytes data, std::int64_t now_ns = 0) {
    EXPECT_TRUE(server.on_frame(request(data), now_ns));
    return take_response(server);
  }
};

TEST(SdoServer, ExpeditedDownloadAndUpload) {
  ServerFixture f;
  EXPECT_EQ(f.ask({0x2F, 0x60, 0x60, 0x00, 10, 0, 0, 0}), (Bytes{0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(f.od.get_int(0x6060, 0), 10);
  EXPECT_EQ(f.ask({0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0}), (Bytes{0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(f.od.get_int(0x1017, 0), 100);
  // Expedited without size indication (e=1, s=0): the entry's size is used.
  EXPECT_EQ(f.ask({0x22, 0x17, 0x10, 0x00, 0xC8, 0x00, 0xEE, 0xEE}), (Bytes{0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(f.od.get_int(0x1017, 0), 200);
  EXPECT_EQ(f.ask({0x40, 0x60, 0x60, 0x00, 0, 0, 0, 0}), (Bytes{0x4F, 0x60, 0x60, 0x00, 10, 0, 0, 0}));
  EXPECT_EQ(f.ask({0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0}), (Bytes{0x4B, 0x17, 0x10, 0x00, 0xC8, 0, 0, 0}));
  EXPECT_EQ(f.ask({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), (Bytes{0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0}));
  EXPECT_EQ(f.ask({0x40, 0x18, 0x10, 0x00, 0, 0, 0, 0}), (Bytes{0x4F, 0x18, 0x10, 0x00, 4, 0, 0, 0}));
}

TEST(SdoServer, SegmentedUploadAndDownload) {
  ServerFixture f;
  EXPECT_EQ(f.ask({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), (Bytes{0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0}));
  EXPECT_EQ(f.ask({0x60, 0, 0, 0, 0, 0, 0, 0}), (Bytes{0x00, 'h', 'a', 'p', 't', 'i', 'c', ' '}));
  EXPECT_EQ(f.ask({0x70, 0, 0, 0, 0, 0, 0, 0}), (Bytes{0x15, 'd', 'r', 'i', 'v', 'e', 0, 0}));
  EXPECT_FALSE(f.server.busy());
  // Download 9 bytes into the string 0x2001: 7 + 2.
  EXPECT_EQ(f.ask({0x21, 0x01, 0x20, 0x00, 9, 0, 0, 0}), (Bytes{0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(f.ask({0x00, 'r', 'i', 'g', 'h', 't', ' ', 'y'}), (Bytes{0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(f.od.find(0x2001, 0)->as_string(), "");  // stored only at the end
  EXPECT_EQ(f.ask({0x1B, 'a', 'w', 0, 0, 0, 0, 0}), (Bytes{0x30, 0, 0, 0, 0, 0, 0, 0}));  // n=5, c=1
  EXPECT_EQ(f.od.find(0x2001, 0)->as_string(), "right yaw");
  // Empty value: uploaded as a segmented transfer with one empty last segment.
  ASSERT_TRUE(f.od.set_bytes(0x2001, 0, {}).is_ok());
  EXPECT_EQ(f.ask({0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0}), (Bytes{0x41, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(f.ask({0x60, 0, 0, 0, 0, 0, 0, 0}), (Bytes{0x0F, 0, 0, 0, 0, 0, 0, 0}));
}

TEST(SdoServer, AbortsWithTheRightCodes) {
  ServerFixture f;
  // Unknown object, unknown sub-index.
  EXPECT_EQ(f.ask({0x40, 0x00, 0x30, 0x00, 0, 0, 0, 0}), (Bytes{0x80, 0x00, 0x30, 0x00, 0x00, 0x00, 0x02, 0x06}));
  EXPECT_EQ(f.ask({0x40, 0x18, 0x10, 0x07, 0, 0, 0, 0}), (Bytes{0x80, 0x18, 0x10, 0x07, 0x11, 0x00, 0x09, 0x06}));
  // Read-only, write-only.
  EXPECT_EQ(f.ask({0x2B, 0x41, 0x60, 0x00, 1, 0, 0, 0}), (Bytes{0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06}));
  EXPECT_EQ(f.ask({0x40, 0x40, 0x60, 0x00, 0, 0, 0, 0}), (Bytes{0x80, 0x40, 0x60, 0x00, 0x01, 0x00, 0x01, 0x06}));
  // Length: 4 bytes into a u16 (expedited), 10 bytes announced for a u16 (segmented).
  EXPECT_EQ(f.ask({0x23, 0x40, 0x60, 0x00, 1, 0, 0, 0}), (Bytes{0x80, 0x40, 0x60, 0x00, 0x12, 0x00, 0x07, 0x06}));
  EXPECT_EQ(f.ask({0x2F, 0x40, 0x60, 0x00, 1, 0, 0, 0}), (Bytes{0x80, 0x40, 0x60, 0x00, 0x13, 0x00, 0x07, 0x06}));
  EXPECT_EQ(f.ask({0x21, 0x40, 0x60, 0x00, 10, 0, 0, 0}), (Bytes{0x80, 0x40, 0x60, 0x00, 0x12, 0x00, 0x07, 0x06}));
  // Value range (0x6071 max 1000 = 0x03E8).
  EXPECT_EQ(f.ask({0x2B, 0x71, 0x60, 0x00, 0xE9, 0x03, 0, 0}), (Bytes{0x80, 0x71, 0x60, 0x00, 0x31, 0x00, 0x09, 0x06}));
  // Block download / upload and the undefined specifier 7.
  EXPECT_EQ(f.ask({0xC6, 0x08, 0x10, 0x00, 0, 0, 0, 0})[0], 0x80);
  EXPECT_EQ(f.server.last_abort_code(), kAbortCommandSpecifier);
  EXPECT_EQ(f.ask({0xA4, 0x08, 0x10, 0x00, 0, 0, 0, 0})[0], 0x80);
  EXPECT_EQ(f.ask({0xE0, 0x08, 0x10, 0x00, 0, 0, 0, 0})[0], 0x80);
  // A segment with no transfer running.
  EXPECT_EQ(f.ask({0x60, 0, 0, 0, 0, 0, 0, 0})[0], 0x80);
  EXPECT_EQ(f.server.last_abort_code(), kAbortCommandSpecifier);
}

TEST(SdoServer, WrongToggleAbortsDownloadAndUpload) {
  ServerFixture f;
  EXPECT_EQ(f.ask({0x21, 0x01, 0x20, 0x00, 9, 0, 0, 0})[0], 0x60);
  EXPECT_EQ(f.ask({0x10, 'r', 'i', 'g', 'h', 't', ' ', 'y'}),  // t=1 first
            (Bytes{0x80, 0x01, 0x20, 0x00, 0x00, 0x00, 0x03, 0x05}));
  EXPECT_FALSE(f.server.busy());
  EXPECT_EQ(f.ask({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0})[0], 0x41);
  EXPECT_EQ(f.ask({0x60, 0, 0, 0, 0, 0, 0, 0})[0], 0x00);
  EXPECT_EQ(f.ask({0x60, 0, 0, 0, 0, 0, 0, 0}),  // t=0 again
            (Bytes{0x80, 0x08, 0x10, 0x00, 0x00, 0x00, 0x03, 0x05}));
}

TEST(SdoServer, SegmentedTransferTimesOutAndAbortEndsIt) {
  ServerFixture f;
  f.server.set_timeout_ns(500 * kSdoMs);
  EXPECT_EQ(f.ask({0x21, 0x01, 0x20, 0x00, 9, 0, 0, 0}, 0)[0], 0x60);
  f.server.on_time(500 * kSdoMs);
  EXPECT_FALSE(f.server.next_tx().has_value());
  f.server.on_time(500 * kSdoMs + 1);
  EXPECT_EQ(take_response(f.server), (Bytes{0x80, 0x01, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05}));
  EXPECT_FALSE(f.server.busy());
  // A client abort ends a transfer silently.
  EXPECT_EQ(f.ask({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0})[0], 0x41);
  EXPECT_TRUE(f.server.on_frame(request({0x80, 0x08, 0x10, 0x00, 0, 0, 0, 0x08}), 1));
  EXPECT_FALSE(f.server.next_tx().has_value());
  EXPECT_FALSE(f.server.busy());
  // Frames for another node or of the wrong length are not for this server.
  EXPECT_FALSE(f.server.on_frame(sdo(0x606, {0x40, 0x08, 0x10, 0, 0, 0, 0, 0}), 2));
  can_frame short_request = request({0x40, 0x08, 0x10, 0, 0, 0, 0, 0});
  short_request.len = 4;
  EXPECT_FALSE(f.server.on_frame(short_request, 2));
}

TEST(Sdo, AbortCodeTexts) {
  EXPECT_STREQ(describe_sdo_abort(0x05030000), "toggle bit not alternated");
  EXPECT_STREQ(describe_sdo_abort(0x05040000), "SDO protocol timed out");
  EXPECT_STREQ(describe_sdo_abort(0x05040001), "client/server command specifier not valid or unknown");
  EXPECT_STREQ(describe_sdo_abort(0x06010000), "unsupported access to an object");
  EXPECT_STREQ(describe_sdo_abort(0x06010001), "attempt to read a write-only object");
  EXPECT_STREQ(describe_sdo_abort(0x06010002), "attempt to write a read-only object");
  EXPECT_STREQ(describe_sdo_abort(0x06040041), "object cannot be mapped to the PDO");
  EXPECT_STREQ(describe_sdo_abort(0x06040042),
               "number and length of the mapped objects would exceed the PDO length");
  EXPECT_STREQ(describe_sdo_abort(0x06070010),
               "data type does not match: length of service parameter does not match");
  EXPECT_STREQ(describe_sdo_abort(0x06070012), "data type does not match: length of service parameter too high");
  EXPECT_STREQ(describe_sdo_abort(0x06070013), "data type does not match: length of service parameter too low");
  EXPECT_STREQ(describe_sdo_abort(0x06090011), "sub-index does not exist");
  EXPECT_STREQ(describe_sdo_abort(0x06090030), "invalid value for parameter (value range exceeded)");
  EXPECT_STREQ(describe_sdo_abort(0x06090031), "value of parameter written too high");
  EXPECT_STREQ(describe_sdo_abort(0x06090032), "value of parameter written too low");
  EXPECT_STREQ(describe_sdo_abort(0x08000000), "general error");
  EXPECT_STREQ(describe_sdo_abort(0x08000020), "data cannot be transferred or stored to the application");
  EXPECT_STREQ(describe_sdo_abort(0x08000021),
               "data cannot be transferred or stored to the application because of local control");
  EXPECT_STREQ(describe_sdo_abort(0x08000022),
               "data cannot be transferred or stored to the application because of the present device state");
  EXPECT_STREQ(describe_sdo_abort(0x08000024), "no data available");
  EXPECT_STREQ(describe_sdo_abort(0x12345678), "unknown abort code");
}

// --- client against server --------------------------------------------------------------------

// Moves frames client -> server -> client until both are quiet; returns frames exchanged.
int pump(SdoClient& client, SdoServer& server, std::int64_t& now_ns) {
  int frames = 0;
  for (int guard = 0; guard < 1000; ++guard) {
    bool moved = false;
    if (auto tx = client.next_tx()) {
      server.on_frame(*tx, now_ns);
      moved = true;
      ++frames;
    }
    if (auto tx = server.next_tx()) {
      client.on_frame(*tx, now_ns);
      moved = true;
      ++frames;
    }
    now_ns += 100'000;
    if (!moved) break;
  }
  return frames;
}

TEST(Sdo, ClientAgainstServerRandomSizes) {
  std::array<std::uint8_t, 512> domain{};
  ObjectDictionary od;
  build_dictionary(od, domain);
  SdoServer server(od, kSdoNode);
  SdoClient client;
  std::mt19937 random(20261125);
  std::uniform_int_distribution<int> byte(0, 255);
  std::int64_t now = 0;
  std::vector<std::size_t> sizes = {0, 1, 2, 3, 4, 5, 6, 7, 8, 13, 14, 15, 300};
  std::uniform_int_distribution<std::size_t> any_size(0, 300);
  for (int i = 0; i < 200; ++i) sizes.push_back(any_size(random));
  for (const std::size_t size : sizes) {
    std::vector<std::uint8_t> written(size);
    for (auto& b : written) b = static_cast<std::uint8_t>(byte(random));
    ASSERT_TRUE(client.start_download(kSdoNode, 0x2002, 0, written, now).is_ok());
    const int download_frames = pump(client, server, now);
    ASSERT_EQ(client.status(), SdoStatus::done) << size << " " << describe_sdo_abort(client.abort_code());
    EXPECT_EQ(client.transferred_bytes(), size);
    // Frames: expedited 2; segmented 2 + 2 per segment (at least one segment).
    const int segments = static_cast<int>(std::max<std::size_t>(1, (size + 6) / 7));
    EXPECT_EQ(download_frames, (size >= 1 && size <= 4) ? 2 : 2 + 2 * segments) << size;
    const ObjectEntry* entry = od.find(0x2002, 0);
    ASSERT_EQ(entry->bytes().size(), size);
    EXPECT_TRUE(std::equal(written.begin(), written.end(), entry->bytes().begin()));

    std::vector<std::uint8_t> read(size + 3, 0xEE);
    ASSERT_TRUE(client.start_upload(kSdoNode, 0x2002, 0, read, now).is_ok());
    pump(client, server, now);
    ASSERT_EQ(client.status(), SdoStatus::done) << size << " " << describe_sdo_abort(client.abort_code());
    ASSERT_EQ(client.transferred_bytes(), size);
    EXPECT_TRUE(std::equal(written.begin(), written.end(), read.begin()));
    EXPECT_EQ(read[size], 0xEE);
  }
  // Through the pair: unknown object and a refused value arrive as server aborts.
  std::array<std::uint8_t, 4> buffer{};
  ASSERT_TRUE(client.start_upload(kSdoNode, 0x5000, 0, buffer, now).is_ok());
  pump(client, server, now);
  EXPECT_EQ(client.status(), SdoStatus::aborted);
  EXPECT_TRUE(client.aborted_by_server());
  EXPECT_EQ(client.abort_code(), kAbortNoObject);
  const std::uint8_t too_high[2] = {0xE9, 0x03};
  ASSERT_TRUE(client.start_download(kSdoNode, 0x6071, 0, too_high, now).is_ok());
  pump(client, server, now);
  EXPECT_EQ(client.abort_code(), kAbortValueTooHigh);
  // A value beyond the domain's storage is refused when announced.
  std::vector<std::uint8_t> big(domain.size() + 1);
  ASSERT_TRUE(client.start_download(kSdoNode, 0x2002, 0, big, now).is_ok());
  pump(client, server, now);
  EXPECT_EQ(client.abort_code(), kAbortLengthTooHigh);
}

}  // namespace
}  // namespace trainer::hal::canopen
