// libFuzzer target: the SDO client and server against arbitrary frames and times.
//   mode 0: SdoClient download (size from the input) fed arbitrary response frames
//   mode 1: SdoClient upload into a buffer of a size from the input, arbitrary responses
//   mode 2: SdoServer over a small dictionary fed arbitrary request frames
//   mode 3: client and server back to back, the input dropping or duplicating frames
// Invariants besides ASan/UBSan: the client never reports more bytes than its buffer or
// data holds, never stays busy after an abort or a timeout, only sends 8-byte frames to
// 0x600 + node; the server only answers 8-byte frames on 0x580 + node; in mode 3 a
// transfer that ends `done` carries exactly the bytes written.
//
// Input: byte 0 mode, byte 1 size; then records of 12 bytes: flags (u8: bits 0..3
// frame length, bit 4 another node's id, bit 5 run on_time, bit 6 drop, bit 7 duplicate),
// command byte + 7 data bytes, time step (u16 LE, units of 1 ms), 1 spare byte that
// picks the object in mode 2.
#include <linux/can.h>

#include <array>
#include <cstdint>
#include <cstring>

#include "fuzz_input.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/sdo.hpp"
#include "trainer/hal_canopen/sdo_client.hpp"
#include "trainer/hal_canopen/sdo_server.hpp"

namespace {

using namespace trainer::hal::canopen;  // NOLINT: a fuzz target, one file
using trainer::fuzz::FuzzInput;

constexpr std::uint8_t kFuzzNode = 5;
constexpr std::int64_t kStepNs = 1'000'000;

struct Record {
  std::uint8_t flags = 0;
  can_frame frame{};
  std::int64_t step_ns = 0;
  std::uint8_t spare = 0;
};

Record read_record(FuzzInput& input, canid_t own_id) {
  Record record;
  record.flags = input.u8();
  record.frame.can_id = (record.flags & 0x10U) != 0 ? own_id + 1 : own_id;
  record.frame.len = static_cast<std::uint8_t>(record.flags & 0x0FU);
  for (std::uint8_t& byte : record.frame.data) byte = input.u8();
  record.step_ns = static_cast<std::int64_t>(input.u16()) * kStepNs;
  record.spare = input.u8();
  return record;
}

void check_client_frame(const can_frame& frame) {
  FUZZ_CHECK(frame.can_id == kCobSdoRxBase + kFuzzNode && frame.len == 8);
}
void check_server_frame(const can_frame& frame) {
  FUZZ_CHECK(frame.can_id == kCobSdoTxBase + kFuzzNode && frame.len == 8);
}

void check_client(const SdoClient& client, std::size_t capacity) {
  FUZZ_CHECK(client.transferred_bytes() <= capacity);
  const SdoStatus status = client.status();
  FUZZ_CHECK(to_string(status) != nullptr);
  if (status == SdoStatus::aborted || status == SdoStatus::timed_out) {
    FUZZ_CHECK(describe_sdo_abort(client.abort_code()) != nullptr);
    // A server may send any code (even 0); the client's own aborts carry a real one.
    FUZZ_CHECK(client.aborted_by_server() || client.abort_code() != 0);
  }
  if (status == SdoStatus::timed_out) FUZZ_CHECK(client.abort_code() == kAbortTimeout);
}

void fuzz_client(FuzzInput& input, bool upload, std::size_t size) {
  std::array<std::uint8_t, 300> storage{};
  for (std::size_t i = 0; i < storage.size(); ++i) storage[i] = static_cast<std::uint8_t>(i);
  SdoClient client;
  client.set_response_timeout_ns(50 * kStepNs);
  std::int64_t now_ns = 0;
  if (upload) {
    FUZZ_CHECK(client.start_upload(kFuzzNode, 0x2000, 1, {storage.data(), size}, now_ns).is_ok());
  } else {
    FUZZ_CHECK(client.start_download(kFuzzNode, 0x2000, 1, {storage.data(), size}, now_ns).is_ok());
  }
  while (!input.empty()) {
    while (const auto tx = client.next_tx()) check_client_frame(*tx);
    const Record record = read_record(input, kCobSdoTxBase + kFuzzNode);
    now_ns += record.step_ns;
    const bool was_busy = client.busy();
    const bool used = client.on_frame(record.frame, now_ns);
    FUZZ_CHECK(!used || was_busy);
    if ((record.flags & 0x20U) != 0) client.on_time(now_ns);
    check_client(client, size);
    if (!client.busy() && (record.flags & 0xC0U) == 0xC0U) {  // start the other direction
      if (upload) {
        (void)client.start_download(kFuzzNode, 0x2000, 2, {storage.data(), record.spare % (size + 1)}, now_ns);
      } else {
        (void)client.start_upload(kFuzzNode, 0x2000, 2, {storage.data(), record.spare % (size + 1)}, now_ns);
      }
    }
  }
  while (const auto tx = client.next_tx()) check_client_frame(*tx);
}

void build_fuzz_dictionary(ObjectDictionary& od, std::span<std::uint8_t> domain) {
  (void)od.add({.index = 0x1000, .sub = 0, .type = DataType::u32, .access = Access::constant, .value = 402});
  (void)od.add({.index = 0x1017, .sub = 0, .type = DataType::u16, .access = Access::rw, .value = 0});
  (void)od.add({.index = 0x6040, .sub = 0, .type = DataType::u16, .access = Access::wo});
  (void)od.add({.index = 0x6041, .sub = 0, .type = DataType::u16, .access = Access::ro});
  (void)od.add({.index = 0x6060, .sub = 0, .type = DataType::i8, .access = Access::rw, .min = 0, .max = 10});
  (void)od.add({.index = 0x6071, .sub = 0, .type = DataType::i16, .access = Access::rw, .min = -1000, .max = 1000});
  (void)od.add_string(0x1008, 0, Access::rw, "fuzz drive");
  (void)od.add_domain(0x2000, 1, Access::rw, domain, 10);
}

constexpr std::uint16_t kFuzzIndices[] = {0x1000, 0x1017, 0x6040, 0x6041, 0x6060, 0x6071, 0x1008, 0x2000, 0x3000};

void fuzz_server(FuzzInput& input) {
  std::array<std::uint8_t, 200> domain{};
  ObjectDictionary od;
  build_fuzz_dictionary(od, domain);
  SdoServer server(od, kFuzzNode);
  server.set_timeout_ns(30 * kStepNs);
  std::int64_t now_ns = 0;
  while (!input.empty()) {
    Record record = read_record(input, kCobSdoRxBase + kFuzzNode);
    // Let the spare byte point initiate requests at existing objects now and then.
    if ((record.spare & 0x80U) != 0) {
      const std::uint16_t index = kFuzzIndices[record.spare % std::size(kFuzzIndices)];
      record.frame.data[1] = static_cast<std::uint8_t>(index & 0xFFU);
      record.frame.data[2] = static_cast<std::uint8_t>(index >> 8);
      record.frame.data[3] = index == 0x2000 ? 1 : 0;
    }
    now_ns += record.step_ns;
    (void)server.on_frame(record.frame, now_ns);
    if ((record.flags & 0x20U) != 0) server.on_time(now_ns);
    while (const auto tx = server.next_tx()) check_server_frame(*tx);
    const ObjectEntry* domain_entry = od.find(0x2000, 1);
    FUZZ_CHECK(domain_entry != nullptr && domain_entry->bytes().size() <= domain.size());
    const auto mode = od.get_int(0x6060, 0);
    FUZZ_CHECK(mode && *mode >= 0 && *mode <= 10);
  }
}

// Client and server back to back; the input drops or duplicates frames and moves time.
void fuzz_pair(FuzzInput& input, std::size_t size) {
  std::array<std::uint8_t, 200> written{};
  std::array<std::uint8_t, 200> read{};
  for (std::size_t i = 0; i < written.size(); ++i) written[i] = static_cast<std::uint8_t>(i * 31 + size);
  std::array<std::uint8_t, 200> domain = written;  // its first 10 bytes are the initial value
  ObjectDictionary od;
  build_fuzz_dictionary(od, domain);
  SdoServer server(od, kFuzzNode);
  SdoClient client;
  client.set_response_timeout_ns(20 * kStepNs);
  const std::size_t length = size % (domain.size() + 1);
  std::int64_t now_ns = 0;
  bool downloading = true;
  FUZZ_CHECK(client.start_download(kFuzzNode, 0x2000, 1, {written.data(), length}, now_ns).is_ok());
  while (!input.empty()) {
    const Record record = read_record(input, 0);
    now_ns += record.step_ns / 8;
    if (auto request = client.next_tx()) {
      check_client_frame(*request);
      if ((record.flags & 0x40U) == 0) (void)server.on_frame(*request, now_ns);
      if ((record.flags & 0x80U) != 0) (void)server.on_frame(*request, now_ns);
    }
    if (auto response = server.next_tx()) {
      check_server_frame(*response);
      if ((record.flags & 0x04U) == 0) (void)client.on_frame(*response, now_ns);
      if ((record.flags & 0x08U) != 0) (void)client.on_frame(*response, now_ns);
    }
    client.on_time(now_ns);
    server.on_time(now_ns);
    check_client(client, length);
    if (client.status() == SdoStatus::done) {
      if (downloading) {
        FUZZ_CHECK(client.transferred_bytes() == length);
        const ObjectEntry* entry = od.find(0x2000, 1);
        FUZZ_CHECK(entry->bytes().size() == length &&
                   std::memcmp(entry->bytes().data(), written.data(), length) == 0);
      } else {
        FUZZ_CHECK(client.transferred_bytes() == od.find(0x2000, 1)->bytes().size());
        FUZZ_CHECK(std::memcmp(read.data(), written.data(), client.transferred_bytes()) == 0);
      }
    }
    if (!client.busy()) {
      downloading = (record.spare & 1U) != 0;
      if (downloading) {
        (void)client.start_download(kFuzzNode, 0x2000, 1, {written.data(), length}, now_ns);
      } else {
        (void)client.start_upload(kFuzzNode, 0x2000, 1, {read.data(), length}, now_ns);
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzInput input(data, size);
  const std::uint8_t mode = input.u8();
  const std::size_t transfer_size = static_cast<std::size_t>(input.u8()) + (mode & 0x10U ? 45U : 0U);
  switch (mode & 3U) {
    case 0: fuzz_client(input, false, transfer_size); break;
    case 1: fuzz_client(input, true, transfer_size); break;
    case 2: fuzz_server(input); break;
    default: fuzz_pair(input, transfer_size); break;
  }
  return 0;
}
