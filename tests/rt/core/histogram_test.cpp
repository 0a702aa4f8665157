// Tests for core::LatencyHistogram: bin geometry over every bin, resolution, percentiles
// against exact order statistics, exact min/max/mean, merge, overflow, clamping, empty state.
#include "trainer/core/histogram.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>

namespace trainer::core {
namespace {

constexpr std::int64_t kOverflowThresholdNs = std::int64_t{1} << LatencyHistogram::kMaxExponent;
constexpr std::size_t kLastBin = LatencyHistogram::kBinCount - 1;

// The histogram is ~9 KiB; keep it off the test's stack.
std::unique_ptr<LatencyHistogram> make_histogram() {
  return std::make_unique<LatencyHistogram>();
}

void expect_same_contents(const LatencyHistogram& actual, const LatencyHistogram& expected) {
  EXPECT_EQ(actual.count(), expected.count());
  EXPECT_EQ(actual.overflow_count(), expected.overflow_count());
  EXPECT_EQ(actual.min_ns(), expected.min_ns());
  EXPECT_EQ(actual.max_ns(), expected.max_ns());
  EXPECT_DOUBLE_EQ(actual.mean_ns(), expected.mean_ns());
  for (std::size_t i = 0; i < LatencyHistogram::kBinCount; ++i) {
    ASSERT_EQ(actual.bin_count(i), expected.bin_count(i)) << "bin " << i;
  }
  for (double fraction : {0.0, 0.1, 0.5, 0.9, 0.99, 0.999, 1.0}) {
    EXPECT_EQ(actual.percentile_ns(fraction), expected.percentile_ns(fraction)) << fraction;
  }
}

TEST(LatencyHistogram, BinCountMatchesTheDocumentedLayout) {
  // 64 exact bins, then 32 sub-bins for each power of two from 2^6 up to 2^39.
  EXPECT_EQ(LatencyHistogram::kBinCount, 64u + 34u * 32u);
  EXPECT_EQ(LatencyHistogram::bin_lower_ns(0), 0);
  EXPECT_EQ(LatencyHistogram::bin_upper_ns(kLastBin), kOverflowThresholdNs);
}

TEST(LatencyHistogram, EveryBinContainsItsEdgesAndBinsAreContiguous) {
  for (std::size_t i = 0; i < LatencyHistogram::kBinCount; ++i) {
    const std::int64_t lower = LatencyHistogram::bin_lower_ns(i);
    const std::int64_t upper = LatencyHistogram::bin_upper_ns(i);
    ASSERT_LT(lower, upper) << "bin " << i;
    ASSERT_EQ(LatencyHistogram::bin_index(lower), i) << "lower edge of bin " << i;
    ASSERT_EQ(LatencyHistogram::bin_index(upper - 1), i) << "last value of bin " << i;
    ASSERT_EQ(LatencyHistogram::bin_index(lower + (upper - lower) / 2), i) << "middle of bin " << i;
    if (i > 0) {
      ASSERT_EQ(LatencyHistogram::bin_index(lower - 1), i - 1) << "just below bin " << i;
    }
    if (i < kLastBin) {
      ASSERT_EQ(upper, LatencyHistogram::bin_lower_ns(i + 1)) << "gap after bin " << i;
      ASSERT_EQ(LatencyHistogram::bin_index(upper), i + 1) << "upper edge of bin " << i;
    }
  }
}

TEST(LatencyHistogram, ValuesAtAndAroundPowersOfTwoLandInTheirBin) {
  for (int exponent = 0; exponent < LatencyHistogram::kMaxExponent; ++exponent) {
    const std::int64_t power = std::int64_t{1} << exponent;
    for (std::int64_t value : {power - 1, power, power + 1}) {
      const std::size_t index = LatencyHistogram::bin_index(value);
      EXPECT_LE(LatencyHistogram::bin_lower_ns(index), value) << value;
      EXPECT_LT(value, LatencyHistogram::bin_upper_ns(index)) << value;
    }
  }
  // A deterministic spread of values over the whole range.
  std::uint64_t state = 0x9E3779B97F4A7C15u;
  for (int i = 0; i < 100000; ++i) {
    state = state * 6364136223846793005u + 1442695040888963407u;
    const auto value = static_cast<std::int64_t>(state >> (24 + (state & 15u)));
    const std::size_t index = LatencyHistogram::bin_index(value);
    ASSERT_LE(LatencyHistogram::bin_lower_ns(index), value) << value;
    ASSERT_LT(value, LatencyHistogram::bin_upper_ns(index)) << value;
  }
}

TEST(LatencyHistogram, ExactBelow64AndRelativeWidthAtMostOneThirtySecondAbove) {
  for (std::size_t i = 0; i < LatencyHistogram::kBinCount; ++i) {
    const std::int64_t lower = LatencyHistogram::bin_lower_ns(i);
    const std::int64_t width = LatencyHistogram::bin_upper_ns(i) - lower;
    if (lower < LatencyHistogram::kLinearLimit) {
      ASSERT_EQ(width, 1) << "bin " << i;
    } else {
      ASSERT_LE(width * 32, lower) << "bin " << i << " lower " << lower << " width " << width;
    }
  }
}

TEST(LatencyHistogram, EmptyHistogramReportsZero) {
  auto histogram = make_histogram();
  EXPECT_EQ(histogram->count(), 0u);
  EXPECT_EQ(histogram->overflow_count(), 0u);
  EXPECT_EQ(histogram->min_ns(), 0);
  EXPECT_EQ(histogram->max_ns(), 0);
  EXPECT_EQ(histogram->mean_ns(), 0.0);
  EXPECT_EQ(histogram->percentile_ns(0.5), 0);
  EXPECT_EQ(histogram->percentile_ns(1.0), 0);
}

TEST(LatencyHistogram, UniformSequencePercentilesWithinBinResolution) {
  constexpr std::int64_t kSamples = 100000;
  auto histogram = make_histogram();
  for (std::int64_t value = 1; value <= kSamples; ++value) histogram->record(value);

  EXPECT_EQ(histogram->count(), static_cast<std::uint64_t>(kSamples));
  EXPECT_EQ(histogram->min_ns(), 1);
  EXPECT_EQ(histogram->max_ns(), kSamples);
  EXPECT_EQ(histogram->mean_ns(), 50000.5);
  EXPECT_EQ(histogram->overflow_count(), 0u);

  // For the sequence 1..N the sample of rank r is r itself. The histogram reports the last
  // value of the bin holding that rank, so it may be above the exact order statistic by less
  // than one bin width (<= 1/32 = 3.125 % of the value); 3.2 % leaves room for rounding of
  // fraction * N. It must never be below (the report is a conservative bound).
  for (std::int64_t per_mille = 1; per_mille <= 1000; ++per_mille) {
    const double fraction = static_cast<double>(per_mille) / 1000.0;
    const std::int64_t exact = (per_mille * kSamples + 999) / 1000;  // ceil(fraction * N)
    const std::int64_t reported = histogram->percentile_ns(fraction);
    ASSERT_GE(reported, exact) << "fraction " << fraction;
    ASSERT_LE(static_cast<double>(reported - exact), 0.032 * static_cast<double>(exact))
        << "fraction " << fraction << " exact " << exact << " reported " << reported;
  }
  EXPECT_EQ(histogram->percentile_ns(0.0), 1);
  EXPECT_EQ(histogram->percentile_ns(1.0), kSamples);  // clamped to the exact maximum
  EXPECT_EQ(histogram->percentile_ns(-1.0), 1);        // fractions are clamped to 0..1
  EXPECT_EQ(histogram->percentile_ns(2.0), kSamples);
}

TEST(LatencyHistogram, SmallValuesAreExact) {
  auto histogram = make_histogram();
  for (std::int64_t value : {3, 3, 10, 40, 63}) histogram->record(value);
  EXPECT_EQ(histogram->percentile_ns(0.4), 3);
  EXPECT_EQ(histogram->percentile_ns(0.6), 10);
  EXPECT_EQ(histogram->percentile_ns(0.8), 40);
  EXPECT_EQ(histogram->percentile_ns(1.0), 63);
  EXPECT_EQ(histogram->bin_count(3), 2u);
  EXPECT_EQ(histogram->bin_count(63), 1u);
}

TEST(LatencyHistogram, MinMaxMeanAreExactNotBinned) {
  auto histogram = make_histogram();
  const std::int64_t values[] = {1'000'003, 777, 12'345'678, 99'999, 1'000'003};
  long double sum = 0;
  for (std::int64_t value : values) {
    histogram->record(value);
    sum += static_cast<long double>(value);
  }
  EXPECT_EQ(histogram->min_ns(), 777);
  EXPECT_EQ(histogram->max_ns(), 12'345'678);
  EXPECT_DOUBLE_EQ(histogram->mean_ns(), static_cast<double>(sum / 5));
  EXPECT_EQ(histogram->percentile_ns(1.0), 12'345'678);
}

TEST(LatencyHistogram, MergeEqualsRecordingBoth) {
  auto first = make_histogram();
  auto second = make_histogram();
  auto both = make_histogram();
  std::uint64_t state = 12345;
  for (int i = 0; i < 20000; ++i) {
    state = state * 6364136223846793005u + 1442695040888963407u;
    const auto value = static_cast<std::int64_t>(state >> 40);  // 0 .. 2^24
    LatencyHistogram& target = (i % 3 == 0) ? *first : *second;
    target.record(value);
    both->record(value);
  }
  for (std::int64_t value : {std::int64_t{-4}, kOverflowThresholdNs + 5}) {
    second->record(value);
    both->record(value);
  }
  first->merge(*second);
  expect_same_contents(*first, *both);
}

TEST(LatencyHistogram, MergeWithEmptyOnEitherSide) {
  auto empty = make_histogram();
  auto filled = make_histogram();
  for (std::int64_t value : {500, 20, 90000}) filled->record(value);
  auto reference = make_histogram();
  *reference = *filled;

  filled->merge(*empty);
  expect_same_contents(*filled, *reference);

  empty->merge(*filled);  // empty target takes min and max from the source
  expect_same_contents(*empty, *reference);
  EXPECT_EQ(empty->min_ns(), 20);
}

TEST(LatencyHistogram, OverflowCountedFromTwoToTheFortyNanoseconds) {
  auto histogram = make_histogram();
  histogram->record(kOverflowThresholdNs - 1);
  EXPECT_EQ(histogram->overflow_count(), 0u);
  EXPECT_EQ(histogram->bin_count(kLastBin), 1u);
  histogram->record(kOverflowThresholdNs);
  EXPECT_EQ(histogram->overflow_count(), 1u);
  histogram->record(std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(histogram->overflow_count(), 2u);
  EXPECT_EQ(histogram->bin_count(kLastBin), 3u);  // overflow lands in the last bin
  EXPECT_EQ(histogram->count(), 3u);
  EXPECT_EQ(histogram->max_ns(), std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(LatencyHistogram::bin_index(std::numeric_limits<std::int64_t>::max()), kLastBin);
  // A percentile in the overflow bin reports at least the overflow threshold.
  EXPECT_GE(histogram->percentile_ns(1.0), kOverflowThresholdNs - 1);
}

TEST(LatencyHistogram, NegativeValuesClampToZero) {
  auto histogram = make_histogram();
  histogram->record(-5);
  histogram->record(std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(LatencyHistogram::bin_index(-1), 0u);
  EXPECT_EQ(histogram->count(), 2u);
  EXPECT_EQ(histogram->bin_count(0), 2u);
  EXPECT_EQ(histogram->min_ns(), 0);
  EXPECT_EQ(histogram->max_ns(), 0);
  EXPECT_EQ(histogram->mean_ns(), 0.0);
  EXPECT_EQ(histogram->percentile_ns(0.5), 0);
}

TEST(LatencyHistogram, ResetReturnsToEmpty) {
  auto histogram = make_histogram();
  for (std::int64_t value : {std::int64_t{5}, std::int64_t{5000}, kOverflowThresholdNs}) {
    histogram->record(value);
  }
  histogram->reset();
  expect_same_contents(*histogram, *make_histogram());
  histogram->record(42);
  EXPECT_EQ(histogram->min_ns(), 42);
  EXPECT_EQ(histogram->max_ns(), 42);
}

}  // namespace
}  // namespace trainer::core
