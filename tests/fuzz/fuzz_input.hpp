// Reads fixed-size fields from a libFuzzer input; past the end every read returns 0 and
// empty() turns true, so a target consumes records until the input runs out.
#pragma once

#include <cstddef>
#include <cstdint>

namespace trainer::fuzz {

class FuzzInput {
 public:
  FuzzInput(const std::uint8_t* data, std::size_t size) noexcept : data_(data), size_(size) {}

  bool empty() const noexcept { return offset_ >= size_; }
  std::uint8_t u8() noexcept { return offset_ < size_ ? data_[offset_++] : 0; }
  std::uint16_t u16() noexcept {
    const std::uint16_t low = u8();
    return static_cast<std::uint16_t>(low | (u8() << 8));
  }
  std::uint32_t u32() noexcept {
    const std::uint32_t low = u16();
    return low | (static_cast<std::uint32_t>(u16()) << 16);
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t offset_ = 0;
};

// Stops the fuzzer with a crash report when an invariant does not hold.
#define FUZZ_CHECK(condition) \
  do {                        \
    if (!(condition)) __builtin_trap(); \
  } while (false)

}  // namespace trainer::fuzz
