// Concurrent producer/consumer test for core::LogRing (label `concurrency`, also run under
// TSan): 200,000 records written as fast as possible against a consumer draining at its own
// pace. Every record is either popped, whole and in order, or counted as dropped.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "trainer/core/log_ring.hpp"

namespace trainer::core {
namespace {

constexpr std::uint64_t kRecordCount = 200'000;
constexpr const char* kFormat = "cycle {} torque {} mNm joint {} {}";

bool record_is_whole(const LogRecord& record, std::uint64_t sequence) {
  return record.format == kFormat && record.arg_count == 4 &&
         record.time_ns == static_cast<std::int64_t>(sequence) * 1000 &&
         record.level == (sequence % 2 == 0 ? LogLevel::info : LogLevel::warning) &&
         record.args[0].kind == LogArg::Kind::unsigned_integer && record.args[0].u == sequence &&
         record.args[1].kind == LogArg::Kind::signed_integer &&
         record.args[1].i == -static_cast<std::int64_t>(sequence) &&
         record.args[2].kind == LogArg::Kind::floating &&
         record.args[2].f == static_cast<double>(sequence) * 0.25 &&
         record.args[3].kind == LogArg::Kind::text;
}

TEST(LogRingConcurrency, EveryRecordIsPoppedInOrderOrCountedAsDropped) {
  auto ring = std::make_unique<LogRing>();
  std::atomic<bool> producer_done{false};
  std::uint64_t accepted = 0;
  std::uint64_t refused = 0;

  std::thread producer([&] {
    for (std::uint64_t sequence = 0; sequence < kRecordCount; ++sequence) {
      const bool written = ring->write(static_cast<std::int64_t>(sequence) * 1000,
                                       sequence % 2 == 0 ? LogLevel::info : LogLevel::warning,
                                       kFormat, sequence, -static_cast<std::int64_t>(sequence),
                                       static_cast<double>(sequence) * 0.25, "pitch");
      if (written) {
        ++accepted;
      } else {
        ++refused;
      }
      // Every so often let the consumer catch up, so both the dropping and the flowing
      // regimes are exercised whatever the scheduler does.
      if (sequence % 4096 == 0) std::this_thread::yield();
    }
    producer_done.store(true, std::memory_order_release);
  });

  std::uint64_t popped = 0;
  std::uint64_t out_of_order = 0;
  std::uint64_t damaged = 0;
  bool have_previous = false;
  std::uint64_t previous_sequence = 0;
  LogRecord record;
  auto consume = [&] {
    const std::uint64_t sequence = record.args[0].u;
    if (!record_is_whole(record, sequence)) ++damaged;
    if (have_previous && sequence <= previous_sequence) ++out_of_order;
    have_previous = true;
    previous_sequence = sequence;
    ++popped;
  };
  for (;;) {
    const bool done = producer_done.load(std::memory_order_acquire);
    if (ring->pop(record)) {
      consume();
    } else if (done) {
      break;  // the producer had finished before this empty pop: nothing more will come
    }
  }
  producer.join();
  while (ring->pop(record)) consume();  // defensive: must find nothing

  RecordProperty("popped", std::to_string(popped));
  RecordProperty("dropped", std::to_string(ring->dropped()));
  EXPECT_EQ(damaged, 0u);
  EXPECT_EQ(out_of_order, 0u);
  EXPECT_GT(popped, 0u);
  EXPECT_EQ(popped, accepted);
  EXPECT_EQ(ring->dropped(), refused);
  EXPECT_EQ(popped + ring->dropped(), kRecordCount);
  // The first record always fits in an empty ring.
  EXPECT_TRUE(have_previous);
}

}  // namespace
}  // namespace trainer::core
