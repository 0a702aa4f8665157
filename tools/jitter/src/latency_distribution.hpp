// One latency distribution in a form both sides of the comparison share: the trainer's
// log-linear LatencyHistogram (ns, bins of at most 3.1 %) and cyclictest's histogram (whole
// microseconds, truncated) become lists of half-open bins [lower, upper) with counts, so the
// percentiles, the CSV files and the plot come from one piece of code and one convention.
//
// Percentile convention (both sides): the value at fraction f is the upper edge of the bin that
// holds the sample of rank ceil(f * n), clamped to the bound on the largest sample. It is an
// upper bound of the true order statistic, at most one bin width above it: ≤ 3.1 % (≤ 1 ns
// below 64 ns) for the trainer, ≤ 1 µs for cyclictest.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/core/histogram.hpp"

namespace trainer::tools::jitter {

inline constexpr std::int64_t kNanosecondsPerMicrosecond = 1000;
inline double to_us(std::int64_t ns) { return static_cast<double>(ns) / 1000.0; }

struct LatencyBin {
  std::int64_t lower_ns = 0;  // inclusive
  std::int64_t upper_ns = 0;  // exclusive, > lower_ns
  std::uint64_t count = 0;    // > 0
};

// The percentiles every report shows, in this order.
struct PercentileSet {
  double p50_us = 0.0;
  double p90_us = 0.0;
  double p99_us = 0.0;
  double p99_9_us = 0.0;
  double max_us = 0.0;  // the bound on the largest sample (exact for the trainer)
};

class LatencyDistribution {
 public:
  LatencyDistribution() = default;

  // Bins sorted by lower edge, not overlapping, every count > 0; largest_ns bounds every
  // sample from above and lies within the last bin (lower_ns <= largest_ns <= upper_ns).
  // The error says which bin breaks which rule.
  static core::Expected<LatencyDistribution> from_bins(std::vector<LatencyBin> bins,
                                                       std::int64_t largest_ns);
  // Every non-empty bin of the trainer's histogram; its exact max bounds the largest sample
  // (the open-ended overflow bin is closed at max + 1 ns).
  static LatencyDistribution from_histogram(const core::LatencyHistogram& histogram);

  const std::vector<LatencyBin>& bins() const noexcept { return bins_; }
  std::uint64_t count() const noexcept { return count_; }
  std::int64_t largest_ns() const noexcept { return largest_ns_; }

  // See the convention above; fraction in [0, 1]; 0 when empty.
  std::int64_t percentile_ns(double fraction) const noexcept;
  PercentileSet percentiles() const noexcept;
  // Samples in bins whose lower edge is at or above `threshold_ns` (a count of samples at or
  // above it when the threshold falls on a bin edge, as whole-microsecond thresholds do for
  // cyclictest).
  std::uint64_t count_at_or_above(std::int64_t threshold_ns) const noexcept;
  // Mean of the bin midpoints weighted by count (an estimate within half a bin width).
  double midpoint_mean_ns() const noexcept;

  // "lower_us,upper_us,count" then one row per bin, in microseconds with ns precision.
  std::string to_csv() const;

 private:
  std::vector<LatencyBin> bins_;
  std::uint64_t count_ = 0;
  std::int64_t largest_ns_ = 0;
};

// trainer / cyclictest for each percentile; a side whose value is 0 gives 0 (no ratio).
PercentileSet percentile_ratios(const PercentileSet& trainer, const PercentileSet& cyclictest);

// Names accepted by --ratio-at: "p50", "p90", "p99", "p99.9", "max".
core::Expected<double> percentile_by_name(const PercentileSet& set, const std::string& name);

}  // namespace trainer::tools::jitter
