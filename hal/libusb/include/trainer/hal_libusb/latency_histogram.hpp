// LatencyHistogram: a fixed histogram of durations (no heap, O(1) record), for the USB
// backend's OUT -> device -> IN round trip. Bins of kBinNs up to kBinCount * kBinNs; longer
// durations go to one overflow bin (counted, and the maximum is kept exactly).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace trainer::hal::libusb {

class LatencyHistogram {
 public:
  static constexpr std::int64_t kBinNs = 10'000;  // 10 us
  static constexpr std::size_t kBinCount = 4000;  // 0 .. 40 ms, then overflow

  void clear() noexcept { *this = LatencyHistogram{}; }
  void record(std::int64_t duration_ns) noexcept {
    if (duration_ns < 0) duration_ns = 0;
    const auto bin = static_cast<std::size_t>(duration_ns / kBinNs);
    if (bin < kBinCount) {
      ++bins_[bin];
    } else {
      ++overflow_;
    }
    if (count_ == 0 || duration_ns < min_ns_) min_ns_ = duration_ns;
    if (duration_ns > max_ns_) max_ns_ = duration_ns;
    sum_ns_ += duration_ns;
    ++count_;
  }

  std::uint64_t count() const noexcept { return count_; }
  std::uint64_t overflow() const noexcept { return overflow_; }
  std::int64_t min_ns() const noexcept { return min_ns_; }
  std::int64_t max_ns() const noexcept { return max_ns_; }
  double mean_ns() const noexcept {
    return count_ == 0 ? 0.0 : static_cast<double>(sum_ns_) / static_cast<double>(count_);
  }
  // The upper edge of the bin holding the q-quantile (0 < q <= 1), i.e. a bound within one
  // bin width above the true percentile; the exact maximum when it lies in the overflow bin.
  // 0 when nothing was recorded.
  std::int64_t percentile_ns(double q) const noexcept {
    if (count_ == 0) return 0;
    const auto rank = static_cast<std::uint64_t>(q * static_cast<double>(count_) + 0.999999);
    const std::uint64_t target = rank < 1 ? 1 : (rank > count_ ? count_ : rank);
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBinCount; ++i) {
      seen += bins_[i];
      if (seen >= target) {
        const std::int64_t edge = static_cast<std::int64_t>(i + 1) * kBinNs;
        return edge < max_ns_ ? edge : max_ns_;
      }
    }
    return max_ns_;
  }

 private:
  std::array<std::uint64_t, kBinCount> bins_{};
  std::uint64_t overflow_ = 0;
  std::uint64_t count_ = 0;
  std::int64_t min_ns_ = 0;
  std::int64_t max_ns_ = 0;
  std::int64_t sum_ns_ = 0;
};

}  // namespace trainer::hal::libusb
