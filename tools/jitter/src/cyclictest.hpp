// cyclictest, the reference the trainer's wake-up latency is compared with: the command line
// that runs it at the trainer's period, priority, CPU, memory locking and PM QoS request, and
// the parser of the histogram file it writes (--histfile, one thread).
//
// The histogram file of `cyclictest -t1 -h LIMIT --histfile=F` (rt-tests 2.x):
//   # Histogram
//   000000 000000          one line per whole microsecond 0 .. LIMIT-1: latency, count
//   ...                    (cyclictest truncates each latency to whole microseconds)
//   # Total: 000059998     samples inside the histogram (overflows excluded)
//   # Min Latencies: 00015
//   # Avg Latencies: 00021
//   # Max Latencies: 07840 over every sample, overflows included
//   # Histogram Overflows: 00002
//   # Histogram Overflow at cycle number:
//   # Thread 0: 01234 05678
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "latency_distribution.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::tools::jitter {

struct CyclictestHistogram {
  std::vector<std::uint64_t> counts;  // counts[k]: samples with k <= latency < k + 1 µs
  std::uint64_t in_range = 0;         // "# Total:" (equals the sum of counts)
  std::uint64_t overflows = 0;        // samples at or above counts.size() µs
  std::int64_t min_us = 0;            // as printed (truncated)
  std::int64_t avg_us = 0;            // as printed (truncated mean of truncated samples)
  std::int64_t max_us = 0;            // as printed (truncated)

  std::int64_t limit_us() const noexcept { return static_cast<std::int64_t>(counts.size()); }
  std::uint64_t samples() const noexcept { return in_range + overflows; }
  // The bins as a LatencyDistribution: [k, k + 1) µs per non-empty k, the overflows as one
  // bin [limit, max + 1) µs, and max + 1 µs as the bound on the largest sample.
  LatencyDistribution distribution() const;
};

// Parses the text of a histogram file; `source` (the file name) starts every error message,
// followed by the line number and what was expected there.
core::Expected<CyclictestHistogram> parse_cyclictest_histogram(std::string_view text,
                                                               std::string_view source);

struct CyclictestSettings {
  std::string executable = "cyclictest";
  std::int64_t period_us = 1000;
  int priority = 0;             // 0 = SCHED_OTHER (--policy=other), else SCHED_FIFO
  int cpu = -1;                 // -1 = not pinned
  bool lock_memory = true;      // -m
  int cpu_dma_latency_us = -1;  // --latency=N; -1 = no request (--laptop)
  std::uint64_t loops = 0;      // -l; 0 = until SIGINT
  std::int64_t histogram_limit_us = 20000;
  std::string histogram_file;
};

// argv of the run, executable first.
std::vector<std::string> cyclictest_arguments(const CyclictestSettings& settings);

}  // namespace trainer::tools::jitter
