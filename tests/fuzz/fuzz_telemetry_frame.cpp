// libFuzzer target: arbitrary datagrams through the telemetry stream's decoder (rt/telemetry,
// docs/telemetry.md) — what the graphics host's viewer reads from the network. Besides memory
// and UB errors (ASan+UBSan) it checks invariants:
//  - a refusal names a byte offset inside the datagram and a detail text;
//  - a frame the decoder accepts re-encodes to exactly the input bytes when its minor version
//    is this reader's; from an older minor (1.0 frames: the seeds) to the same bytes but for
//    the version byte and the CRC; from a newer minor (its extra bytes are skipped) to a frame
//    that decodes.
// Random bytes almost never pass the magic, length and CRC checks, so each input is also
// decoded "repaired": magic and major version set, the length field made the input's and the
// CRC recomputed, which reaches the section, count, index and value checks.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <span>
#include <vector>

#include "trainer/telemetry/wire_format.hpp"

namespace {

namespace wire = trainer::telemetry;

void check(std::span<const std::byte> bytes) {
  static auto frame = std::make_unique<wire::Frame>();
  static auto again = std::make_unique<wire::Frame>();
  static std::vector<std::byte> encoded(wire::kMaxDatagramBytes);
  const wire::DecodeResult result = wire::decode(bytes, *frame);
  if (!result.ok()) {
    if (result.offset > bytes.size()) std::abort();
    if (result.detail == nullptr || wire::to_string(result.error) == nullptr) std::abort();
    return;
  }
  const wire::EncodeResult re = wire::encode(*frame, encoded);
  if (!re.ok()) std::abort();
  const std::uint8_t minor = std::to_integer<std::uint8_t>(bytes[5]);
  if (minor <= wire::kVersionMinor) {
    if (re.bytes != bytes.size()) std::abort();
    if (minor < wire::kVersionMinor) {
      // Written as this version: the same frame under the older version byte and its CRC.
      encoded[5] = bytes[5];
      std::memset(encoded.data() + 8, 0, 4);
      const std::uint32_t crc = wire::crc32({encoded.data(), re.bytes});
      for (std::size_t i = 0; i < 4; ++i)
        encoded[8 + i] = std::byte(static_cast<std::uint8_t>(crc >> (8 * i)));
    }
    if (std::memcmp(encoded.data(), bytes.data(), re.bytes) != 0) std::abort();
  } else if (!wire::decode({encoded.data(), re.bytes}, *again).ok()) {
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto* bytes = reinterpret_cast<const std::byte*>(data);
  check({bytes, size});
  if (size < wire::kHeaderBytes || size > wire::kMaxDatagramBytes) return 0;
  std::vector<std::byte> repaired(bytes, bytes + size);
  for (std::size_t i = 0; i < wire::kMagic.size(); ++i) repaired[i] = std::byte{wire::kMagic[i]};
  repaired[4] = std::byte{wire::kVersionMajor};
  repaired[6] = std::byte(static_cast<std::uint8_t>(size));
  repaired[7] = std::byte(static_cast<std::uint8_t>(size >> 8));
  std::memset(repaired.data() + 8, 0, 4);
  const std::uint32_t crc = wire::crc32(repaired);
  for (std::size_t i = 0; i < 4; ++i)
    repaired[8 + i] = std::byte(static_cast<std::uint8_t>(crc >> (8 * i)));
  check(repaired);
  return 0;
}
