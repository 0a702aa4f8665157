// LatestValue<T>: a lock-free triple buffer that hands the newest value from one producer
// thread to one consumer thread. The producer never waits for the consumer and the consumer
// never sees a half-written value; values the consumer did not take in time are overwritten
// (the newest wins), which is what the USB backend wants for "the latest IN report" and "the
// next OUT report". Wait-free on both sides (one atomic exchange each), no heap, no syscalls.
//
// Roles are fixed: exactly one thread calls the producer pair (back() / publish()) and exactly
// one thread calls the consumer pair (take() / front()). The three slots are the producer's
// back slot, the middle slot (handed over through the atomic index) and the consumer's front
// slot; the atomic holds the middle slot's index and a "fresh" bit set by publish() and
// cleared by take().
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace trainer::hal::libusb {

template <typename T>
class LatestValue {
 public:
  LatestValue() noexcept = default;
  LatestValue(const LatestValue&) = delete;
  LatestValue& operator=(const LatestValue&) = delete;

  // Producer: the slot to fill, then publish() to hand it over (the old middle slot, if the
  // consumer did not take it, becomes the next back slot: that value is dropped).
  T& back() noexcept { return slots_[back_]; }
  // Returns true when the value published before this one was never taken (overwritten).
  bool publish() noexcept {
    const std::uint8_t old = middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh),
                                              std::memory_order_acq_rel);
    back_ = static_cast<std::uint8_t>(old & kIndexMask);
    return (old & kFresh) != 0;
  }

  // Consumer: true when a value newer than the last one taken was published; front() is
  // then that value (and stays valid until the next take()).
  bool take() noexcept {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
    const std::uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = static_cast<std::uint8_t>(old & kIndexMask);
    return true;
  }
  const T& front() const noexcept { return slots_[front_]; }

  // Setup only (no other thread running): forget everything published.
  void reset(const T& value) noexcept {
    for (T& slot : slots_) slot = value;
    back_ = 0;
    middle_.store(1, std::memory_order_relaxed);
    front_ = 2;
  }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  std::array<T, 3> slots_{};
  std::uint8_t back_ = 0;                 // producer's
  std::atomic<std::uint8_t> middle_{1};   // shared: index | kFresh
  std::uint8_t front_ = 2;                // consumer's
};

}  // namespace trainer::hal::libusb
