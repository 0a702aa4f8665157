#include "trainer/core/arena.hpp"

#include <cstdint>
#include <cstring>
#include <string>

namespace trainer::core {

namespace {
std::size_t round_up(std::size_t value, std::size_t alignment) {
  return (value + alignment - 1) / alignment * alignment;
}
}  // namespace

Expected<Arena> Arena::create(std::size_t capacity_bytes) {
  if (capacity_bytes == 0) return make_error("arena: capacity must be positive");
  if (capacity_bytes > static_cast<std::size_t>(-1) - kAlignment) {
    return make_error("arena: capacity of " + std::to_string(capacity_bytes) +
                      " bytes is impossible");
  }
  const std::size_t capacity = round_up(capacity_bytes, kAlignment);
  auto* block = static_cast<std::byte*>(
      ::operator new(capacity, std::align_val_t{kAlignment}, std::nothrow));
  if (block == nullptr) {
    return make_error("arena: cannot allocate " + std::to_string(capacity) + " bytes");
  }
  // Touch every page now so the RT path never takes a first-touch page fault
  // (with mlockall(MCL_FUTURE) the pages also stay resident).
  std::memset(block, 0, capacity);
  return Arena(block, capacity);
}

Arena::Arena(Arena&& other) noexcept
    : block_(other.block_),
      capacity_(other.capacity_),
      used_(other.used_),
      refused_after_seal_(other.refused_after_seal_),
      sealed_(other.sealed_) {
  other.block_ = nullptr;
  other.capacity_ = 0;
  other.used_ = 0;
}

Arena& Arena::operator=(Arena&& other) noexcept {
  if (this != &other) {
    if (block_ != nullptr) ::operator delete(block_, std::align_val_t{kAlignment});
    block_ = other.block_;
    capacity_ = other.capacity_;
    used_ = other.used_;
    refused_after_seal_ = other.refused_after_seal_;
    sealed_ = other.sealed_;
    other.block_ = nullptr;
    other.capacity_ = 0;
    other.used_ = 0;
  }
  return *this;
}

Arena::~Arena() {
  if (block_ != nullptr) ::operator delete(block_, std::align_val_t{kAlignment});
}

Error Arena::count_overflow_error(std::string_view what) {
  return make_error("arena: element count for '" + std::string(what) +
                    "' overflows the addressable size");
}

Expected<void*> Arena::allocate_bytes(std::size_t bytes, std::size_t alignment,
                                      std::string_view what) {
  if (sealed_) {
    ++refused_after_seal_;
    return make_error("arena: request for '" + std::string(what) +
                      "' after the loop was armed (arena is sealed)");
  }
  if (alignment == 0 || (alignment & (alignment - 1)) != 0) {
    return make_error("arena: alignment for '" + std::string(what) + "' is not a power of two");
  }
  if (block_ == nullptr) {
    return make_error("arena: request for '" + std::string(what) + "' on a moved-from arena");
  }
  // Align the real address, not the offset: the block itself is only kAlignment-aligned.
  const auto base = reinterpret_cast<std::uintptr_t>(block_);
  const std::size_t start = round_up(base + used_, alignment) - base;
  if (start > capacity_ || bytes > capacity_ - start) {
    return make_error("arena exhausted: '" + std::string(what) + "' needs " +
                      std::to_string(bytes) + " bytes but only " +
                      std::to_string(start > capacity_ ? 0 : capacity_ - start) + " of " +
                      std::to_string(capacity_) +
                      " remain; raise memory.arena_kib in the scene file");
  }
  used_ = start + bytes;
  return static_cast<void*>(block_ + start);
}

}  // namespace trainer::core
