#include "trainer/core/histogram.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace trainer::core {

std::size_t LatencyHistogram::bin_index(std::int64_t value_ns) noexcept {
  if (value_ns < 0) value_ns = 0;
  if (value_ns < kLinearLimit) return static_cast<std::size_t>(value_ns);
  const auto value = static_cast<std::uint64_t>(value_ns);
  const int exponent = static_cast<int>(std::bit_width(value)) - 1;  // >= kSubBinBits + 1
  if (exponent >= kMaxExponent) return kBinCount - 1;
  const std::uint64_t sub = (value >> (exponent - kSubBinBits)) - (std::uint64_t{1} << kSubBinBits);
  return static_cast<std::size_t>(kLinearLimit) +
         static_cast<std::size_t>(exponent - kSubBinBits - 1) * (std::size_t{1} << kSubBinBits) +
         static_cast<std::size_t>(sub);
}

std::int64_t LatencyHistogram::bin_lower_ns(std::size_t index) noexcept {
  if (index < static_cast<std::size_t>(kLinearLimit)) return static_cast<std::int64_t>(index);
  const std::size_t offset = index - static_cast<std::size_t>(kLinearLimit);
  const int exponent = static_cast<int>(offset >> kSubBinBits) + kSubBinBits + 1;
  const std::uint64_t sub = offset & ((std::size_t{1} << kSubBinBits) - 1);
  return static_cast<std::int64_t>(((std::uint64_t{1} << kSubBinBits) + sub)
                                   << (exponent - kSubBinBits));
}

std::int64_t LatencyHistogram::bin_upper_ns(std::size_t index) noexcept {
  if (index < static_cast<std::size_t>(kLinearLimit)) return static_cast<std::int64_t>(index) + 1;
  const std::size_t offset = index - static_cast<std::size_t>(kLinearLimit);
  const int exponent = static_cast<int>(offset >> kSubBinBits) + kSubBinBits + 1;
  return bin_lower_ns(index) + (std::int64_t{1} << (exponent - kSubBinBits));
}

void LatencyHistogram::record(std::int64_t value_ns) noexcept {
  if (value_ns < 0) value_ns = 0;
  const std::size_t index = bin_index(value_ns);
  ++bins_[index];
  if (index == kBinCount - 1 && value_ns >= bin_upper_ns(kBinCount - 1)) ++overflow_;
  if (count_ == 0) {
    min_ = max_ = value_ns;
  } else {
    min_ = std::min(min_, value_ns);
    max_ = std::max(max_, value_ns);
  }
  ++count_;
  sum_ += static_cast<long double>(value_ns);
}

void LatencyHistogram::reset() noexcept { *this = LatencyHistogram{}; }

void LatencyHistogram::merge(const LatencyHistogram& other) noexcept {
  if (other.count_ == 0) return;
  for (std::size_t i = 0; i < kBinCount; ++i) bins_[i] += other.bins_[i];
  if (count_ == 0) {
    min_ = other.min_;
    max_ = other.max_;
  } else {
    min_ = std::min(min_, other.min_);
    max_ = std::max(max_, other.max_);
  }
  count_ += other.count_;
  overflow_ += other.overflow_;
  sum_ += other.sum_;
}

double LatencyHistogram::mean_ns() const noexcept {
  return count_ == 0 ? 0.0 : static_cast<double>(sum_ / static_cast<long double>(count_));
}

std::int64_t LatencyHistogram::percentile_ns(double fraction) const noexcept {
  if (count_ == 0) return 0;
  fraction = std::clamp(fraction, 0.0, 1.0);
  // Rank of the sample at this percentile (1-based), at least the first sample.
  auto rank = static_cast<std::uint64_t>(std::ceil(fraction * static_cast<double>(count_)));
  rank = std::clamp<std::uint64_t>(rank, 1, count_);
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < kBinCount; ++i) {
    seen += bins_[i];
    // The last bin is open-ended (overflow): only the exact maximum bounds it.
    if (seen >= rank) return i == kBinCount - 1 ? max_ : std::min(bin_upper_ns(i) - 1, max_);
  }
  return max_;
}

}  // namespace trainer::core
