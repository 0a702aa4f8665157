// Bump arena: one block allocated and pre-faulted at configure time, carved into spans for
// everything the haptic cycle touches. Exhaustion is a configuration error returned before
// the loop is armed; after seal() every further request fails and is counted, never
// satisfied from the heap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <span>
#include <string_view>
#include <type_traits>

#include "trainer/core/expected.hpp"

namespace trainer::core {

class Arena {
 public:
  static constexpr std::size_t kAlignment = 64;  // cache line; also the model-image alignment

  // Allocates and pre-faults `capacity_bytes` (rounded up to kAlignment). Setup path only.
  static Expected<Arena> create(std::size_t capacity_bytes);

  Arena(Arena&&) noexcept;
  Arena& operator=(Arena&&) noexcept;
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;
  ~Arena();

  // Value-initialised array of `count` T, aligned to max(alignof(T), kAlignment).
  // `what` names the request in the error message ("duct mode matrix").
  template <class T>
  Expected<std::span<T>> allocate_array(std::size_t count, std::string_view what) {
    static_assert(std::is_trivially_destructible_v<T>, "arena never runs destructors");
    if (count > static_cast<std::size_t>(-1) / sizeof(T)) return count_overflow_error(what);
    auto raw = allocate_bytes(count * sizeof(T), alignof(T) > kAlignment ? alignof(T) : kAlignment, what);
    if (!raw) return std::move(raw).error();
    // Construct element by element: array placement-new may add an ABI cookie.
    T* typed = static_cast<T*>(raw.value());
    for (std::size_t i = 0; i < count; ++i) new (typed + i) T();
    return std::span<T>(typed, count);
  }

  template <class T, class... Args>
  Expected<T*> create_object(std::string_view what, Args&&... args) {
    static_assert(std::is_trivially_destructible_v<T>, "arena never runs destructors");
    auto raw = allocate_bytes(sizeof(T), alignof(T) > kAlignment ? alignof(T) : kAlignment, what);
    if (!raw) return std::move(raw).error();
    return new (raw.value()) T{std::forward<Args>(args)...};
  }

  Expected<void*> allocate_bytes(std::size_t bytes, std::size_t alignment, std::string_view what);

  // After seal() the arena refuses every request (and counts them).
  void seal() noexcept { sealed_ = true; }
  bool sealed() const noexcept { return sealed_; }
  std::size_t capacity_bytes() const noexcept { return capacity_; }
  std::size_t used_bytes() const noexcept { return used_; }
  std::uint64_t refused_after_seal() const noexcept { return refused_after_seal_; }

 private:
  Arena(std::byte* block, std::size_t capacity) noexcept : block_(block), capacity_(capacity) {}
  static Error count_overflow_error(std::string_view what);

  std::byte* block_ = nullptr;
  std::size_t capacity_ = 0;
  std::size_t used_ = 0;
  std::uint64_t refused_after_seal_ = 0;
  bool sealed_ = false;
};

}  // namespace trainer::core
