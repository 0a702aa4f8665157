// Concurrent stress test for core::TripleBuffer (label `concurrency`, also run under TSan):
// a writer publishes 1,000,000 snapshots whose every field derives from a sequence number;
// a reader checks that every snapshot it takes is whole (never torn), that sequence numbers
// never go backwards, and that it ends with the final snapshot.
#include <gtest/gtest.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "trainer/core/triple_buffer.hpp"

namespace trainer::core {
namespace {

constexpr std::uint64_t kSnapshotCount = 1'000'000;
constexpr std::size_t kFieldCount = 12;

// Large enough (~120 bytes, two cache lines) that a torn copy would mix generations.
struct Snapshot {
  std::uint64_t sequence = 0;
  std::uint64_t scaled[kFieldCount] = {};   // scaled[i] = sequence * (i + 1)
  double half = 0.0;                        // sequence / 2
  std::uint64_t check = ~std::uint64_t{0};  // ~sequence, written last
};

void fill(Snapshot& snapshot, std::uint64_t sequence) {
  snapshot.sequence = sequence;
  for (std::size_t i = 0; i < kFieldCount; ++i) snapshot.scaled[i] = sequence * (i + 1);
  snapshot.half = static_cast<double>(sequence) * 0.5;
  snapshot.check = ~sequence;
}

bool consistent(const Snapshot& snapshot) {
  const std::uint64_t sequence = snapshot.sequence;
  for (std::size_t i = 0; i < kFieldCount; ++i) {
    if (snapshot.scaled[i] != sequence * (i + 1)) return false;
  }
  return snapshot.half == static_cast<double>(sequence) * 0.5 && snapshot.check == ~sequence;
}

TEST(TripleBufferConcurrency, ReaderNeverSeesATornOrOlderSnapshot) {
  auto buffer = std::make_unique<TripleBuffer<Snapshot>>();
  std::atomic<bool> writer_done{false};

  std::thread writer([&buffer, &writer_done] {
    for (std::uint64_t sequence = 1; sequence <= kSnapshotCount; ++sequence) {
      fill(buffer->write_slot(), sequence);  // in place, as the RT thread does
      buffer->publish();
    }
    writer_done.store(true, std::memory_order_release);
  });

  std::uint64_t last_sequence = 0;
  std::uint64_t snapshots_taken = 0;
  std::uint64_t torn = 0;
  std::uint64_t changed_while_held = 0;
  std::uint64_t backwards = 0;
  std::uint64_t repeated = 0;
  std::uint64_t first_bad_sequence = 0;
  for (;;) {
    // Read the flag before updating: if the writer had finished by then, this update (or the
    // previous one) holds the final snapshot.
    const bool done = writer_done.load(std::memory_order_acquire);
    const bool fresh = buffer->update();
    const Snapshot& snapshot = buffer->latest();
    if (!consistent(snapshot)) {
      if (torn++ == 0) first_bad_sequence = snapshot.sequence;
    }
    if (fresh) {
      ++snapshots_taken;
      if (snapshot.sequence < last_sequence) ++backwards;
      if (snapshot.sequence == last_sequence) ++repeated;  // update() promised a newer one
      last_sequence = snapshot.sequence;
    } else {
      // The held snapshot must stay untouched until the next update(), however many times
      // the writer publishes meanwhile.
      if (snapshot.sequence != last_sequence) ++changed_while_held;
      if (done) break;
    }
  }
  writer.join();

  RecordProperty("snapshots_taken", std::to_string(snapshots_taken));
  EXPECT_EQ(torn, 0u) << "first torn snapshot claimed sequence " << first_bad_sequence;
  EXPECT_EQ(changed_while_held, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(repeated, 0u);
  EXPECT_GT(snapshots_taken, 0u);
  EXPECT_LE(snapshots_taken, kSnapshotCount);
  EXPECT_EQ(last_sequence, kSnapshotCount);
  EXPECT_EQ(buffer->latest().sequence, kSnapshotCount);
  EXPECT_TRUE(consistent(buffer->latest()));
  EXPECT_EQ(buffer->published_count(), kSnapshotCount);
  EXPECT_FALSE(buffer->update());
}

}  // namespace
}  // namespace trainer::core
