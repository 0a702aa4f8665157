// Concurrent producer/consumer test for core::SpscRing (label `concurrency`, also run under
// TSan): 200,000 records of 1 KiB (the size of the recording's per-cycle record) pushed as fast
// as possible against a consumer draining at its own pace. Every record is either popped, whole
// and in order, or counted as dropped.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>

#include "trainer/core/spsc_ring.hpp"

namespace trainer::core {
namespace {

constexpr std::uint64_t kRingRecords = 200'000;

struct Big {
  std::uint64_t sequence;
  std::array<std::uint64_t, 127> body;  // every word = sequence * 3 + index
};

Big make_big(std::uint64_t sequence) {
  Big big{};
  big.sequence = sequence;
  for (std::size_t k = 0; k < big.body.size(); ++k) big.body[k] = sequence * 3 + k;
  return big;
}

bool big_is_whole(const Big& big) {
  for (std::size_t k = 0; k < big.body.size(); ++k) {
    if (big.body[k] != big.sequence * 3 + k) return false;
  }
  return true;
}

TEST(SpscRingConcurrency, EveryRecordIsPoppedWholeInOrderOrCountedAsDropped) {
  auto ring = std::make_unique<SpscRing<Big, 256>>();
  std::atomic<bool> producer_done{false};
  std::uint64_t accepted = 0;
  std::thread producer([&] {
    for (std::uint64_t sequence = 0; sequence < kRingRecords; ++sequence) {
      if (ring->push(make_big(sequence))) ++accepted;
      if (sequence % 1024 == 0) std::this_thread::yield();
    }
    producer_done.store(true, std::memory_order_release);
  });
  std::uint64_t popped = 0;
  std::uint64_t damaged = 0;
  std::uint64_t out_of_order = 0;
  std::uint64_t previous = 0;
  bool have_previous = false;
  Big big{};
  const auto consume = [&] {
    if (!big_is_whole(big)) ++damaged;
    if (have_previous && big.sequence <= previous) ++out_of_order;
    have_previous = true;
    previous = big.sequence;
    ++popped;
  };
  for (;;) {
    const bool done = producer_done.load(std::memory_order_acquire);
    if (ring->pop(big)) {
      consume();
    } else if (done) {
      break;
    }
  }
  producer.join();
  while (ring->pop(big)) consume();
  EXPECT_EQ(damaged, 0U);
  EXPECT_EQ(out_of_order, 0U);
  EXPECT_EQ(popped, accepted);
  EXPECT_EQ(popped + ring->dropped(), kRingRecords);
}

}  // namespace
}  // namespace trainer::core
