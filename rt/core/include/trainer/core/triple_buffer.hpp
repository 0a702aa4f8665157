// Lock-free, wait-free single-writer / single-reader state exchange (triple buffer).
// The RT thread writes a whole snapshot into its back slot and publishes it with one atomic
// exchange; a non-RT reader takes the newest published snapshot with one atomic exchange.
// Neither side ever waits or sees a torn snapshot, and the writer never blocks on a slow
// reader (the reader just skips intermediate snapshots).
#pragma once

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace trainer::core {

template <class T>
class TripleBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "snapshots are copied by value");

 public:
  TripleBuffer() noexcept = default;
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  // Writer side (RT thread): fill write_slot(), then publish().
  T& write_slot() noexcept { return slots_[back_].value; }
  void publish() noexcept {
    const std::uint8_t previous = middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh),
                                                   std::memory_order_acq_rel);
    back_ = previous & kIndexMask;
    published_count_.fetch_add(1, std::memory_order_relaxed);
  }
  void publish(const T& snapshot) noexcept {
    write_slot() = snapshot;
    publish();
  }

  // Reader side (one non-RT thread): true if a snapshot newer than the last read was taken.
  // `latest()` stays valid until the next call to update().
  bool update() noexcept {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & kIndexMask;
    return true;
  }
  const T& latest() const noexcept { return slots_[front_].value; }
  std::uint64_t published_count() const noexcept {
    return published_count_.load(std::memory_order_relaxed);
  }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  struct alignas(64) Slot {
    T value{};
  };
  Slot slots_[3];
  alignas(64) std::atomic<std::uint8_t> middle_{1};
  alignas(64) std::uint8_t back_ = 0;    // owned by the writer
  alignas(64) std::uint8_t front_ = 2;   // owned by the reader
  std::atomic<std::uint64_t> published_count_{0};
};

}  // namespace trainer::core
