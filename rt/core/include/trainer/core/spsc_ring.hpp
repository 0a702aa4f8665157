// Lock-free single-producer / single-consumer ring of trivially copyable values, fixed
// capacity (a power of two, in the type). The producer (the RT thread) never waits: a push
// into a full ring is refused and counted. The consumer (a non-RT thread) pops in order.
// The same scheme as LogRing, for any record type (the session recording's per-cycle record).
// Large: create it on the heap on the setup path.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace trainer::core {

template <class T, std::size_t Capacity>
class SpscRing {
  static_assert(std::is_trivially_copyable_v<T>, "ring values are copied as bytes");
  static_assert(Capacity > 0 && (Capacity & (Capacity - 1)) == 0, "capacity: a power of two");

 public:
  static constexpr std::size_t kCapacity = Capacity;

  // Producer: false (and counted as dropped) when the ring is full.
  bool push(const T& value) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    const std::size_t tail = tail_.load(std::memory_order_acquire);
    if (head - tail == Capacity) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    values_[head & (Capacity - 1)] = value;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  // Producer: true when a push now would be refused.
  bool full() const noexcept {
    return head_.load(std::memory_order_relaxed) - tail_.load(std::memory_order_acquire) ==
           Capacity;
  }

  // Consumer: pops one value; false when empty.
  bool pop(T& out) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t head = head_.load(std::memory_order_acquire);
    if (tail == head) return false;
    out = values_[tail & (Capacity - 1)];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  // Pushes refused because the ring was full (from any thread).
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::array<T, Capacity> values_{};
  alignas(64) std::atomic<std::size_t> head_{0};       // written by the producer
  alignas(64) std::atomic<std::size_t> tail_{0};       // written by the consumer
  alignas(64) std::atomic<std::uint64_t> dropped_{0};  // producer-only writes
};

}  // namespace trainer::core
