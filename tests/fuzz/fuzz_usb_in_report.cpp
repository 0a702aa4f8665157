// libFuzzer target: arbitrary bytes through the USB haptic interface's IN-report decoder
// (hal/usbproto, docs/usb-protocol.md), and the OUT-report and identity decoders on the way.
// Besides memory and UB errors (ASan+UBSan) it checks invariants:
//  - every report a decoder accepts re-encodes to exactly the input bytes;
//  - decode() leaves `out` untouched when it refuses;
//  - a refusal names a status with a text;
//  - decoded counts are in the 24-bit range and extend_count() recovers them.
// Random bytes almost never pass the magic and CRC checks, so each input is also decoded
// "repaired": its first 64 bytes (zero-padded) with the magic set, the version kept or set
// (first input byte's bit 0) and the CRC recomputed, which reaches the channel-count,
// reserved-byte and field checks.
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <span>

#include "fuzz_input.hpp"
#include "trainer/hal_usbproto/protocol.hpp"

namespace {

namespace up = trainer::hal::usbproto;

bool same_in(const up::InReport& a, const up::InReport& b) {
  return a.sequence == b.sequence && a.out_sequence_applied == b.out_sequence_applied &&
         a.device_time_us == b.device_time_us && a.status == b.status && a.buttons == b.buttons &&
         a.channel_count == b.channel_count &&
         std::equal(std::begin(a.counts), std::end(a.counts), std::begin(b.counts));
}

void check_in(std::span<const std::uint8_t> bytes) {
  up::InReport sentinel;
  sentinel.sequence = 0x5A5A;
  sentinel.counts[3] = 77;
  up::InReport decoded = sentinel;
  const up::DecodeStatus status = up::decode(bytes, decoded);
  FUZZ_CHECK(up::to_string(status) != nullptr);
  if (status != up::DecodeStatus::ok) {
    FUZZ_CHECK(same_in(decoded, sentinel));
    return;
  }
  FUZZ_CHECK(bytes.size() == up::kReportSize);
  FUZZ_CHECK(decoded.channel_count <= up::kMaxChannels);
  for (std::size_t i = 0; i < up::kMaxChannels; ++i) {
    const std::int32_t count = decoded.counts[i];
    FUZZ_CHECK(count >= up::kMinWireCount && count <= up::kMaxWireCount);
    FUZZ_CHECK(i < decoded.channel_count || count == 0);
    FUZZ_CHECK(up::wire_count(up::extend_count(12345, count)) == count);
  }
  std::array<std::uint8_t, up::kReportSize> again{};
  FUZZ_CHECK(up::encode(decoded, again) == up::kReportSize);
  FUZZ_CHECK(std::memcmp(again.data(), bytes.data(), up::kReportSize) == 0);
}

void check_out(std::span<const std::uint8_t> bytes) {
  up::OutReport decoded;
  decoded.sequence = 0xA5A5;
  const up::DecodeStatus status = up::decode(bytes, decoded);
  FUZZ_CHECK(up::to_string(status) != nullptr);
  if (status != up::DecodeStatus::ok) {
    FUZZ_CHECK(decoded.sequence == 0xA5A5);
    return;
  }
  FUZZ_CHECK((decoded.flags & ~up::kOutFlagsDefined) == 0);
  std::array<std::uint8_t, up::kReportSize> again{};
  FUZZ_CHECK(up::encode(decoded, again) == up::kReportSize);
  FUZZ_CHECK(std::memcmp(again.data(), bytes.data(), up::kReportSize) == 0);
}

void check_identity(std::span<const std::uint8_t> bytes) {
  up::Identity decoded;
  const up::DecodeStatus status = up::decode(bytes, decoded);
  FUZZ_CHECK(up::to_string(status) != nullptr);
  if (status != up::DecodeStatus::ok) return;
  std::array<std::uint8_t, up::kIdentitySize> again{};
  FUZZ_CHECK(up::encode(decoded, again) == up::kIdentitySize);
  FUZZ_CHECK(std::memcmp(again.data(), bytes.data(), up::kIdentitySize) == 0);
}

// The input's first `N` bytes, zero-padded, with magic, version and CRC made right.
template <std::size_t N>
std::array<std::uint8_t, N> repaired(const std::uint8_t* data, std::size_t size, std::uint8_t magic) {
  std::array<std::uint8_t, N> bytes{};
  std::copy_n(data, std::min(size, N), bytes.begin());
  const bool keep_version = size > 0 && (data[0] & 1U) != 0;
  bytes[0] = magic;
  if (!keep_version) bytes[1] = up::kProtocolVersion;
  bytes[N - 1] = up::crc8(std::span<const std::uint8_t>(bytes).first(N - 1));
  return bytes;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> raw(data, size);
  check_in(raw);
  check_out(raw);
  check_identity(raw);

  const auto in_bytes = repaired<up::kReportSize>(data, size, up::kInMagic);
  check_in(in_bytes);
  const auto out_bytes = repaired<up::kReportSize>(data, size, up::kOutMagic);
  check_out(out_bytes);
  const auto id_bytes = repaired<up::kIdentitySize>(data, size, up::kIdentityMagic);
  check_identity(id_bytes);

  // A repaired IN report with the version kept as 1 fails only on content.
  up::InReport report;
  const up::DecodeStatus status = up::decode(in_bytes, report);
  if (in_bytes[1] == up::kProtocolVersion) {
    FUZZ_CHECK(status == up::DecodeStatus::ok || status == up::DecodeStatus::bad_channel_count ||
               status == up::DecodeStatus::reserved_not_zero);
  }
  return 0;
}
