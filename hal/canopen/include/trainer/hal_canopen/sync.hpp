// SYNC (CiA 301 v4.2, 7.2.5): id 0x080, no data, or one counter byte when the
// synchronous counter overflow value (object 0x1019) is 2..240.
//
// Master: SyncProducer sync(0);            // 0x1019 = 0: no counter
//         send(sync.next());               // once per communication cycle (0x1006)
// Slave:  if (auto s = decode_sync(frame)) { s->counter ... }
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <optional>

namespace trainer::hal::canopen {

inline constexpr std::uint8_t kMaxSyncCounterOverflow = 240;

struct SyncMessage {
  std::optional<std::uint8_t> counter;  // 1..240 when present
};

can_frame encode_sync() noexcept;                      // 0 bytes
can_frame encode_sync(std::uint8_t counter) noexcept;  // 1 byte (pass 1..240)
// nullopt unless id 0x080 data frame with 0 bytes, or 1 byte holding 1..240. A slave
// that receives a SYNC of another length reports EMCY 0x8240 (unexpected SYNC length).
std::optional<SyncMessage> decode_sync(const can_frame& frame) noexcept;

// SYNC producer with the optional counter (0x1019): overflow 0 = no counter byte;
// 2..240 = the counter runs 1, 2, ..., overflow, 1, ... Other values are reserved and
// treated as 0 (valid() is false).
class SyncProducer {
 public:
  explicit SyncProducer(std::uint8_t counter_overflow = 0) noexcept;
  bool valid() const noexcept { return valid_; }
  can_frame next() noexcept;
  // The counter starts again at 1 (CiA 301: after NMT start / reset).
  void reset() noexcept { counter_ = 0; }

 private:
  std::uint8_t overflow_ = 0;
  std::uint8_t counter_ = 0;
  bool valid_ = true;
};

}  // namespace trainer::hal::canopen
