// Single-threaded semantics of core::TripleBuffer (the concurrent stress test is in
// triple_buffer_concurrency_test.cpp).
#include "trainer/core/triple_buffer.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace trainer::core {
namespace {

struct Snapshot {
  std::uint64_t sequence = 0;
  double position_m = 0.0;
};

TEST(TripleBuffer, NothingToReadBeforeTheFirstPublish) {
  TripleBuffer<Snapshot> buffer;
  EXPECT_FALSE(buffer.update());
  EXPECT_FALSE(buffer.update());
  EXPECT_EQ(buffer.latest().sequence, 0u);  // value-initialised
  EXPECT_EQ(buffer.published_count(), 0u);
}

TEST(TripleBuffer, WritingWithoutPublishingIsInvisible) {
  TripleBuffer<Snapshot> buffer;
  buffer.write_slot().sequence = 5;
  EXPECT_FALSE(buffer.update());
  EXPECT_EQ(buffer.latest().sequence, 0u);
  buffer.publish();
  ASSERT_TRUE(buffer.update());
  EXPECT_EQ(buffer.latest().sequence, 5u);
}

TEST(TripleBuffer, UpdateTakesEachPublishOnce) {
  TripleBuffer<Snapshot> buffer;
  buffer.publish(Snapshot{1, 0.5});
  ASSERT_TRUE(buffer.update());
  EXPECT_EQ(buffer.latest().sequence, 1u);
  EXPECT_EQ(buffer.latest().position_m, 0.5);
  EXPECT_FALSE(buffer.update());            // nothing newer
  EXPECT_EQ(buffer.latest().sequence, 1u);  // still readable after a false update
  EXPECT_EQ(buffer.published_count(), 1u);
}

TEST(TripleBuffer, ReaderSkipsIntermediateSnapshotsAndGetsTheNewest) {
  TripleBuffer<Snapshot> buffer;
  for (std::uint64_t sequence = 1; sequence <= 5; ++sequence) {
    buffer.publish(Snapshot{sequence, 0.1 * static_cast<double>(sequence)});
  }
  ASSERT_TRUE(buffer.update());
  EXPECT_EQ(buffer.latest().sequence, 5u);
  EXPECT_FALSE(buffer.update());
  EXPECT_EQ(buffer.published_count(), 5u);
}

TEST(TripleBuffer, AlternatingPublishAndReadNeverShowsAStaleOrFutureSnapshot) {
  // Walks the slot rotation through many cycles, with the writer filling its slot in place
  // (the RT pattern) and sometimes publishing twice between reads.
  TripleBuffer<Snapshot> buffer;
  std::uint64_t sequence = 0;
  for (int round = 0; round < 100; ++round) {
    const int publishes = 1 + round % 3;
    for (int i = 0; i < publishes; ++i) {
      Snapshot& slot = buffer.write_slot();
      slot.sequence = ++sequence;
      slot.position_m = static_cast<double>(sequence) * 2.0;
      buffer.publish();
    }
    ASSERT_TRUE(buffer.update()) << "round " << round;
    EXPECT_EQ(buffer.latest().sequence, sequence);
    EXPECT_EQ(buffer.latest().position_m, static_cast<double>(sequence) * 2.0);
    EXPECT_FALSE(buffer.update());
  }
  EXPECT_EQ(buffer.published_count(), sequence);
}

TEST(TripleBuffer, WriterNeverWritesIntoTheSlotTheReaderHolds) {
  TripleBuffer<Snapshot> buffer;
  buffer.publish(Snapshot{1, 1.0});
  ASSERT_TRUE(buffer.update());
  const Snapshot* held = &buffer.latest();
  // However often the writer publishes without a read, the held snapshot stays intact.
  for (std::uint64_t sequence = 2; sequence < 50; ++sequence) {
    EXPECT_NE(&buffer.write_slot(), held);
    buffer.publish(Snapshot{sequence, 0.0});
    EXPECT_EQ(held->sequence, 1u);
  }
}

}  // namespace
}  // namespace trainer::core
