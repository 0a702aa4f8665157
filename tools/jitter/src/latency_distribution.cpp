#include "latency_distribution.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace trainer::tools::jitter {

namespace {

std::string describe(std::size_t index, const LatencyBin& bin) {
  return "bin " + std::to_string(index) + " [" + std::to_string(bin.lower_ns) + ", " +
         std::to_string(bin.upper_ns) + ") ns";
}

}  // namespace

core::Expected<LatencyDistribution> LatencyDistribution::from_bins(std::vector<LatencyBin> bins,
                                                                   std::int64_t largest_ns) {
  LatencyDistribution distribution;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    const LatencyBin& bin = bins[i];
    if (bin.lower_ns < 0 || bin.upper_ns <= bin.lower_ns) {
      return core::make_error(describe(i, bin) + ": expected 0 <= lower < upper");
    }
    if (bin.count == 0) return core::make_error(describe(i, bin) + ": empty bins are not listed");
    if (i > 0 && bin.lower_ns < bins[i - 1].upper_ns) {
      return core::make_error(describe(i, bin) + ": overlaps or precedes the bin before it");
    }
    distribution.count_ += bin.count;
  }
  if (!bins.empty() && (largest_ns < bins.back().lower_ns || largest_ns > bins.back().upper_ns)) {
    return core::make_error("largest sample bound " + std::to_string(largest_ns) +
                            " ns: expected within the last bin, " +
                            describe(bins.size() - 1, bins.back()));
  }
  distribution.largest_ns_ = bins.empty() ? 0 : largest_ns;
  distribution.bins_ = std::move(bins);
  return distribution;
}

LatencyDistribution LatencyDistribution::from_histogram(const core::LatencyHistogram& histogram) {
  LatencyDistribution distribution;
  const std::int64_t max_ns = histogram.max_ns();
  for (std::size_t i = 0; i < core::LatencyHistogram::kBinCount; ++i) {
    const std::uint64_t count = histogram.bin_count(i);
    if (count == 0) continue;
    LatencyBin bin{core::LatencyHistogram::bin_lower_ns(i), core::LatencyHistogram::bin_upper_ns(i),
                   count};
    // The last bin also holds everything beyond its nominal edge (overflow).
    if (i == core::LatencyHistogram::kBinCount - 1)
      bin.upper_ns = std::max(bin.upper_ns, max_ns + 1);
    distribution.bins_.push_back(bin);
    distribution.count_ += count;
  }
  distribution.largest_ns_ = max_ns;
  return distribution;
}

std::int64_t LatencyDistribution::percentile_ns(double fraction) const noexcept {
  if (count_ == 0) return 0;
  fraction = std::clamp(fraction, 0.0, 1.0);
  auto rank = static_cast<std::uint64_t>(std::ceil(fraction * static_cast<double>(count_)));
  rank = std::clamp<std::uint64_t>(rank, 1, count_);
  std::uint64_t seen = 0;
  for (const LatencyBin& bin : bins_) {
    seen += bin.count;
    if (seen >= rank) return std::min(bin.upper_ns, largest_ns_);
  }
  return largest_ns_;
}

PercentileSet LatencyDistribution::percentiles() const noexcept {
  return PercentileSet{to_us(percentile_ns(0.50)), to_us(percentile_ns(0.90)),
                       to_us(percentile_ns(0.99)), to_us(percentile_ns(0.999)), to_us(largest_ns_)};
}

std::uint64_t LatencyDistribution::count_at_or_above(std::int64_t threshold_ns) const noexcept {
  std::uint64_t total = 0;
  for (const LatencyBin& bin : bins_) {
    if (bin.lower_ns >= threshold_ns) total += bin.count;
  }
  return total;
}

double LatencyDistribution::midpoint_mean_ns() const noexcept {
  if (count_ == 0) return 0.0;
  double sum = 0.0;
  for (const LatencyBin& bin : bins_) {
    sum += 0.5 * static_cast<double>(bin.lower_ns + bin.upper_ns) * static_cast<double>(bin.count);
  }
  return sum / static_cast<double>(count_);
}

std::string LatencyDistribution::to_csv() const {
  std::string csv = "lower_us,upper_us,count\n";
  char row[96];
  for (const LatencyBin& bin : bins_) {
    std::snprintf(row, sizeof row, "%.3f,%.3f,%llu\n", to_us(bin.lower_ns), to_us(bin.upper_ns),
                  static_cast<unsigned long long>(bin.count));
    csv += row;
  }
  return csv;
}

PercentileSet percentile_ratios(const PercentileSet& trainer, const PercentileSet& cyclictest) {
  const auto ratio = [](double a, double b) { return a > 0.0 && b > 0.0 ? a / b : 0.0; };
  return PercentileSet{
      ratio(trainer.p50_us, cyclictest.p50_us), ratio(trainer.p90_us, cyclictest.p90_us),
      ratio(trainer.p99_us, cyclictest.p99_us), ratio(trainer.p99_9_us, cyclictest.p99_9_us),
      ratio(trainer.max_us, cyclictest.max_us)};
}

core::Expected<double> percentile_by_name(const PercentileSet& set, const std::string& name) {
  if (name == "p50") return set.p50_us;
  if (name == "p90") return set.p90_us;
  if (name == "p99") return set.p99_us;
  if (name == "p99.9") return set.p99_9_us;
  if (name == "max") return set.max_us;
  return core::make_error("percentile '" + name + "': expected one of p50, p90, p99, p99.9, max");
}

}  // namespace trainer::tools::jitter
