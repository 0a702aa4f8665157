// The shared percentile convention: the trainer's histogram converted to bins gives the
// percentiles LatencyHistogram itself reports (to its 1 ns inclusive/exclusive difference);
// synthetic bins give the ranks worked out by hand; bad bins are refused; the CSV holds every
// sample; ratios divide like for like.
#include "latency_distribution.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <sstream>
#include <string>

namespace trainer::tools::jitter {
namespace {

TEST(LatencyDistribution, FromTheTrainersHistogramMatchesItsOwnPercentiles) {
  // Latencies like a loaded VM's: mostly 15-60 us, a tail to milliseconds, a few below 64 ns.
  std::mt19937_64 random(12345);
  std::lognormal_distribution<double> body(std::log(25'000.0), 0.35);
  std::uniform_int_distribution<std::int64_t> tail(100'000, 9'000'000);
  core::LatencyHistogram histogram;
  for (int i = 0; i < 50'000; ++i) {
    if (i % 997 == 0) {
      histogram.record(tail(random));
    } else if (i % 4999 == 0) {
      histogram.record(i % 60);
    } else {
      histogram.record(static_cast<std::int64_t>(body(random)));
    }
  }
  const LatencyDistribution distribution = LatencyDistribution::from_histogram(histogram);
  EXPECT_EQ(distribution.count(), histogram.count());
  EXPECT_EQ(distribution.largest_ns(), histogram.max_ns());
  std::uint64_t total = 0;
  for (const LatencyBin& bin : distribution.bins()) {
    EXPECT_GT(bin.count, 0U);
    EXPECT_LT(bin.lower_ns, bin.upper_ns);
    total += bin.count;
  }
  EXPECT_EQ(total, histogram.count());
  for (const double fraction : {0.0, 0.001, 0.1, 0.5, 0.9, 0.99, 0.995, 0.999, 0.9999, 1.0}) {
    // percentile_ns reports the bin's last nanosecond, the distribution its exclusive edge.
    const std::int64_t own = histogram.percentile_ns(fraction);
    const std::int64_t shared = distribution.percentile_ns(fraction);
    EXPECT_GE(shared, own) << fraction;
    EXPECT_LE(shared, own + 1) << fraction;
  }
  EXPECT_NEAR(distribution.midpoint_mean_ns(), histogram.mean_ns(), 0.02 * histogram.mean_ns());
}

TEST(LatencyDistribution, PercentilesAreUpperEdgesClampedToTheLargestSample) {
  // 100 samples: 50 in [10, 11) us, 40 in [20, 22) us, 9 in [30, 40) us, 1 in [100, 200) us
  // whose exact value, 150 us, is known.
  auto distribution = LatencyDistribution::from_bins(
      {{10'000, 11'000, 50}, {20'000, 22'000, 40}, {30'000, 40'000, 9}, {100'000, 200'000, 1}},
      150'000);
  ASSERT_TRUE(distribution) << distribution.error().message;
  EXPECT_EQ(distribution->count(), 100U);
  EXPECT_EQ(distribution->percentile_ns(0.0), 11'000);     // rank 1
  EXPECT_EQ(distribution->percentile_ns(0.50), 11'000);    // rank 50
  EXPECT_EQ(distribution->percentile_ns(0.51), 22'000);    // rank 51
  EXPECT_EQ(distribution->percentile_ns(0.90), 22'000);    // rank 90
  EXPECT_EQ(distribution->percentile_ns(0.99), 40'000);    // rank 99
  EXPECT_EQ(distribution->percentile_ns(0.999), 150'000);  // rank 100: clamped to the max
  const PercentileSet us = distribution->percentiles();
  EXPECT_DOUBLE_EQ(us.p50_us, 11.0);
  EXPECT_DOUBLE_EQ(us.p99_us, 40.0);
  EXPECT_DOUBLE_EQ(us.max_us, 150.0);
  EXPECT_EQ(distribution->count_at_or_above(20'000), 50U);
  EXPECT_EQ(distribution->count_at_or_above(100'000), 1U);
  // Midpoints: (10.5 * 50 + 21 * 40 + 35 * 9 + 150 * 1) / 100 us.
  EXPECT_NEAR(distribution->midpoint_mean_ns(),
              (10'500.0 * 50 + 21'000.0 * 40 + 35'000.0 * 9 + 150'000.0) / 100.0, 1e-6);

  const LatencyDistribution empty;
  EXPECT_EQ(empty.percentile_ns(0.5), 0);
  EXPECT_EQ(empty.count(), 0U);
}

TEST(LatencyDistribution, BadBinsAreRefusedNamingTheBin) {
  auto overlap = LatencyDistribution::from_bins({{0, 2000, 1}, {1000, 3000, 1}}, 2500);
  ASSERT_FALSE(overlap);
  EXPECT_NE(overlap.error().message.find("bin 1 [1000, 3000) ns"), std::string::npos)
      << overlap.error().message;
  auto empty_bin = LatencyDistribution::from_bins({{0, 1000, 0}}, 500);
  ASSERT_FALSE(empty_bin);
  EXPECT_NE(empty_bin.error().message.find("empty"), std::string::npos);
  auto backwards = LatencyDistribution::from_bins({{5000, 5000, 1}}, 5000);
  ASSERT_FALSE(backwards);
  EXPECT_NE(backwards.error().message.find("lower < upper"), std::string::npos);
  auto outside = LatencyDistribution::from_bins({{1000, 2000, 3}}, 9000);
  ASSERT_FALSE(outside);
  EXPECT_NE(outside.error().message.find("largest sample bound 9000 ns"), std::string::npos)
      << outside.error().message;
}

TEST(LatencyDistribution, CsvListsEveryBinAndEverySample) {
  auto distribution =
      LatencyDistribution::from_bins({{20'480, 21'504, 7}, {8'000'000, 8'006'001, 1}}, 8'006'000);
  ASSERT_TRUE(distribution);
  EXPECT_EQ(distribution->to_csv(),
            "lower_us,upper_us,count\n20.480,21.504,7\n8000.000,8006.001,1\n");
}

TEST(PercentileRatios, DivideTrainerByCyclictestPerPercentile) {
  const PercentileSet trainer{20.5, 30.0, 54.0, 600.0, 9000.0};
  const PercentileSet cyclictest{16.0, 24.0, 45.0, 0.0, 7500.0};
  const PercentileSet ratios = percentile_ratios(trainer, cyclictest);
  EXPECT_DOUBLE_EQ(ratios.p50_us, 20.5 / 16.0);
  EXPECT_DOUBLE_EQ(ratios.p90_us, 1.25);
  EXPECT_DOUBLE_EQ(ratios.p99_us, 1.2);
  EXPECT_DOUBLE_EQ(ratios.p99_9_us, 0.0);  // nothing to divide by: no ratio
  EXPECT_DOUBLE_EQ(ratios.max_us, 1.2);

  EXPECT_DOUBLE_EQ(*percentile_by_name(ratios, "p99.9"), 0.0);
  EXPECT_DOUBLE_EQ(*percentile_by_name(trainer, "p50"), 20.5);
  EXPECT_DOUBLE_EQ(*percentile_by_name(trainer, "max"), 9000.0);
  auto unknown = percentile_by_name(trainer, "p95");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("'p95'"), std::string::npos);
}

}  // namespace
}  // namespace trainer::tools::jitter
