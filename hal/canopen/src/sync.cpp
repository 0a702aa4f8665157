// SYNC frames and the counting producer (CiA 301 v4.2, 7.2.5 and object 0x1019).
#include "trainer/hal_canopen/sync.hpp"

#include "trainer/hal_canopen/frame.hpp"

namespace trainer::hal::canopen {

can_frame encode_sync() noexcept { return make_frame(kCobSync, {}); }

can_frame encode_sync(std::uint8_t counter) noexcept {
  const std::uint8_t data[1] = {counter};
  return make_frame(kCobSync, data);
}

std::optional<SyncMessage> decode_sync(const can_frame& frame) noexcept {
  if (!is_data_frame_with_id(frame, kCobSync)) return std::nullopt;
  if (frame.len == 0) return SyncMessage{};
  if (frame.len == 1 && frame.data[0] >= 1 && frame.data[0] <= kMaxSyncCounterOverflow) {
    return SyncMessage{frame.data[0]};
  }
  return std::nullopt;
}

SyncProducer::SyncProducer(std::uint8_t counter_overflow) noexcept {
  // 1 and 241..255 are reserved values of 0x1019.
  valid_ = counter_overflow == 0 ||
           (counter_overflow >= 2 && counter_overflow <= kMaxSyncCounterOverflow);
  overflow_ = valid_ ? counter_overflow : 0;
}

can_frame SyncProducer::next() noexcept {
  if (overflow_ == 0) return encode_sync();
  counter_ = counter_ >= overflow_ ? 1 : static_cast<std::uint8_t>(counter_ + 1);
  return encode_sync(counter_);
}

}  // namespace trainer::hal::canopen
