// cyclictest's histogram file: a file as rt-tests 2.4 writes it (with and without overflows)
// parses into the right counts and percentiles; every kind of malformed input is refused with
// the file name, the line number and what was expected; and the command line mirrors the
// loop's settings.
#include "cyclictest.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <string_view>

namespace trainer::tools::jitter {
namespace {

// Bins 0..limit-1 with the given non-zero counts, then the summary lines, as cyclictest -t1
// -h LIMIT --histfile writes them.
std::string histogram_file(std::size_t limit, const std::vector<std::pair<std::size_t, int>>& bins,
                           std::string_view summary) {
  std::string text = "# Histogram\n";
  char line[32];
  for (std::size_t k = 0; k < limit; ++k) {
    int count = 0;
    for (const auto& [bin, bin_count] : bins) {
      if (bin == k) count = bin_count;
    }
    std::snprintf(line, sizeof line, "%06zu %06d\n", k, count);
    text += line;
  }
  return text.append(summary);
}

constexpr std::string_view kSummary10 =
    "# Total: 000000010\n# Min Latencies: 00015\n# Avg Latencies: 00016\n"
    "# Max Latencies: 00020\n# Histogram Overflows: 00000\n"
    "# Histogram Overflow at cycle number:\n# Thread 0:\n";

std::string error_of(const std::string& text) {
  auto parsed = parse_cyclictest_histogram(text, "ct.txt");
  EXPECT_FALSE(parsed) << "expected a parse error";
  return parsed ? std::string() : parsed.error().message;
}

TEST(CyclictestHistogram, ParsesCountsSummaryAndPercentiles) {
  const std::string text = histogram_file(30, {{15, 1}, {16, 5}, {17, 3}, {20, 1}}, kSummary10);
  auto parsed = parse_cyclictest_histogram(text, "ct.txt");
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_EQ(parsed->limit_us(), 30);
  EXPECT_EQ(parsed->in_range, 10U);
  EXPECT_EQ(parsed->overflows, 0U);
  EXPECT_EQ(parsed->samples(), 10U);
  EXPECT_EQ(parsed->min_us, 15);
  EXPECT_EQ(parsed->avg_us, 16);
  EXPECT_EQ(parsed->max_us, 20);
  EXPECT_EQ(parsed->counts[16], 5U);

  // Whole-microsecond bins [k, k + 1): a percentile is the upper edge of its rank's bin.
  const LatencyDistribution distribution = parsed->distribution();
  EXPECT_EQ(distribution.count(), 10U);
  ASSERT_EQ(distribution.bins().size(), 4U);
  EXPECT_EQ(distribution.bins()[1].lower_ns, 16'000);
  EXPECT_EQ(distribution.bins()[1].upper_ns, 17'000);
  const PercentileSet us = distribution.percentiles();
  EXPECT_DOUBLE_EQ(us.p50_us, 17.0);  // rank 5: 1 + 5 samples up to bin 16
  EXPECT_DOUBLE_EQ(us.p90_us, 18.0);  // rank 9: bin 17
  EXPECT_DOUBLE_EQ(us.p99_us, 21.0);  // rank 10: bin 20
  EXPECT_DOUBLE_EQ(us.max_us, 21.0);  // the 20 us sample lies in [20, 21)
  EXPECT_EQ(distribution.count_at_or_above(17'000), 4U);
}

TEST(CyclictestHistogram, OverflowsBecomeOneBinUpToTheMax) {
  const std::string summary =
      "# Total: 000000998\n# Min Latencies: 00003\n# Avg Latencies: 00005\n"
      "# Max Latencies: 08005\n# Histogram Overflows: 00002\n"
      "# Histogram Overflow at cycle number:\n# Thread 0: 00012 00500\n";
  const std::string text = histogram_file(25, {{3, 500}, {4, 400}, {5, 98}}, summary);
  auto parsed = parse_cyclictest_histogram(text, "ct.txt");
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_EQ(parsed->samples(), 1000U);
  const LatencyDistribution distribution = parsed->distribution();
  EXPECT_EQ(distribution.count(), 1000U);
  ASSERT_EQ(distribution.bins().size(), 4U);
  EXPECT_EQ(distribution.bins().back().lower_ns, 25'000);  // the histogram's limit
  EXPECT_EQ(distribution.bins().back().upper_ns, 8'006'000);
  EXPECT_EQ(distribution.bins().back().count, 2U);
  const PercentileSet us = distribution.percentiles();
  EXPECT_DOUBLE_EQ(us.p99_us, 6.0);       // rank 990 is in bin 5
  EXPECT_DOUBLE_EQ(us.p99_9_us, 8006.0);  // rank 999 is an overflow: bounded by the max
  EXPECT_DOUBLE_EQ(us.max_us, 8006.0);
}

TEST(CyclictestHistogram, BadLinesAreRefusedWithFileAndLine) {
  const std::string good = histogram_file(30, {{15, 1}, {16, 5}, {17, 3}, {20, 1}}, kSummary10);

  std::string bad_count = good;
  bad_count.replace(bad_count.find("000002 000000"), 13, "000002 0x0000");
  std::string message = error_of(bad_count);
  EXPECT_NE(message.find("ct.txt:4:"), std::string::npos) << message;  // header is line 1
  EXPECT_NE(message.find("'000002 0x0000'"), std::string::npos) << message;
  EXPECT_NE(message.find("<latency us> <count>"), std::string::npos) << message;

  std::string two_threads = good;
  two_threads.replace(two_threads.find("000003 000000"), 13, "000003 000000 000001");
  message = error_of(two_threads);
  EXPECT_NE(message.find("ct.txt:5:"), std::string::npos) << message;
  EXPECT_NE(message.find("cyclictest -t1"), std::string::npos) << message;

  std::string skipped = good;
  skipped.erase(skipped.find("000003 000000\n"), 14);
  message = error_of(skipped);
  EXPECT_NE(message.find("ct.txt:5: bin 4: expected bin 3"), std::string::npos) << message;

  std::string two_minima = good;
  two_minima.replace(two_minima.find("# Min Latencies: 00015"), 22, "# Min Latencies: 00015 00017");
  message = error_of(two_minima);
  EXPECT_NE(message.find("ct.txt:33:"), std::string::npos) << message;  // after 30 bins, Total
  EXPECT_NE(message.find("Min Latencies"), std::string::npos) << message;
}

TEST(CyclictestHistogram, InconsistentOrIncompleteFilesAreRefused) {
  const std::vector<std::pair<std::size_t, int>> bins{{15, 1}, {16, 5}, {17, 3}, {20, 1}};

  std::string message = error_of(histogram_file(30, bins, ""));
  EXPECT_NE(message.find("ct.txt: no '# Total:' line"), std::string::npos) << message;

  std::string wrong_total(kSummary10);
  wrong_total.replace(wrong_total.find("000000010"), 9, "000000011");
  message = error_of(histogram_file(30, bins, wrong_total));
  EXPECT_NE(message.find("'# Total: 11' but the histogram lines add up to 10"), std::string::npos)
      << message;

  std::string wrong_max(kSummary10);
  wrong_max.replace(wrong_max.find("Max Latencies: 00020"), 20, "Max Latencies: 00019");
  message = error_of(histogram_file(30, bins, wrong_max));
  EXPECT_NE(message.find("'# Max Latencies: 19' disagrees with the bins"), std::string::npos)
      << message;

  message = error_of("# Histogram\n# Total: 0\n");
  EXPECT_NE(message.find("no histogram lines"), std::string::npos) << message;

  const std::string empty_summary =
      "# Total: 000000000\n# Min Latencies: 00000\n# Avg Latencies: 00000\n"
      "# Max Latencies: 00000\n# Histogram Overflows: 00000\n";
  message = error_of(histogram_file(5, {}, empty_summary));
  EXPECT_NE(message.find("no samples"), std::string::npos) << message;
}

TEST(CyclictestCommand, MirrorsTheLoopsSettings) {
  CyclictestSettings rt;
  rt.period_us = 100;
  rt.priority = 80;
  rt.cpu = 1;
  rt.lock_memory = true;
  rt.cpu_dma_latency_us = 0;
  rt.loops = 60000;
  rt.histogram_limit_us = 20000;
  rt.histogram_file = "/tmp/h.txt";
  const std::vector<std::string> expected{
      "cyclictest", "-q", "-t1",         "-i100",   "--policy=fifo", "-p80",
      "-a1",        "-m", "--latency=0", "-l60000", "-h20000",       "--histfile=/tmp/h.txt"};
  EXPECT_EQ(cyclictest_arguments(rt), expected);

  CyclictestSettings plain = rt;
  plain.priority = 0;
  plain.cpu = -1;
  plain.lock_memory = false;
  plain.cpu_dma_latency_us = -1;
  plain.loops = 0;  // until SIGINT
  const std::vector<std::string> args = cyclictest_arguments(plain);
  const auto has = [&](const std::string& argument) {
    return std::find(args.begin(), args.end(), argument) != args.end();
  };
  EXPECT_TRUE(has("--policy=other"));
  EXPECT_TRUE(has("-p0"));
  EXPECT_TRUE(has("--laptop"));  // no PM QoS request, as the loop makes none
  EXPECT_FALSE(has("-m"));
  EXPECT_FALSE(has("-a1"));
  EXPECT_FALSE(std::any_of(args.begin(), args.end(), [](const std::string& a) {
    return a.rfind("-l", 0) == 0 && a != "--laptop";
  }));
}

}  // namespace
}  // namespace trainer::tools::jitter
