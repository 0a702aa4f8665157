// Fixed-bin latency histogram (no allocation) for nanosecond durations.
// Log-linear bins: exact below 64 ns, then 32 linear sub-bins per power of two, so a bin's
// width is at most 1/32 (3.1 %) of its value, up to 2^40 ns (~18 min); larger values land in
// the last bin and are counted as overflow. Percentiles report the upper edge of the bin
// holding the requested rank (a conservative bound), clamped to the exact maximum seen.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace trainer::core {

class LatencyHistogram {
 public:
  static constexpr int kSubBinBits = 5;
  static constexpr std::int64_t kLinearLimit = std::int64_t{1} << (kSubBinBits + 1);  // 64
  static constexpr int kMaxExponent = 40;
  static constexpr std::size_t kBinCount =
      static_cast<std::size_t>(kLinearLimit) +
      static_cast<std::size_t>(kMaxExponent - kSubBinBits - 1) * (std::size_t{1} << kSubBinBits);

  void record(std::int64_t value_ns) noexcept;
  void reset() noexcept;
  void merge(const LatencyHistogram& other) noexcept;

  std::uint64_t count() const noexcept { return count_; }
  std::uint64_t overflow_count() const noexcept { return overflow_; }
  std::int64_t min_ns() const noexcept { return count_ ? min_ : 0; }
  std::int64_t max_ns() const noexcept { return count_ ? max_ : 0; }
  double mean_ns() const noexcept;
  // Upper bound of the value below which `fraction` (0..1) of samples lie; 0 when empty.
  std::int64_t percentile_ns(double fraction) const noexcept;

  static std::size_t bin_index(std::int64_t value_ns) noexcept;
  static std::int64_t bin_lower_ns(std::size_t index) noexcept;
  static std::int64_t bin_upper_ns(std::size_t index) noexcept;  // exclusive
  std::uint64_t bin_count(std::size_t index) const noexcept { return bins_[index]; }

 private:
  std::array<std::uint64_t, kBinCount> bins_{};
  std::uint64_t count_ = 0;
  std::uint64_t overflow_ = 0;
  std::int64_t min_ = 0;
  std::int64_t max_ = 0;
  long double sum_ = 0;
};

}  // namespace trainer::core
