// The receiver-side sequencer: newest wins; duplicates, late and stale frames dropped and
// counted; gaps counted, late arrivals of skipped numbers subtracted from the loss.
#include "trainer/telemetry/sequencer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

namespace trainer::telemetry {
namespace {

using Verdict = Sequencer::Verdict;

TEST(Sequencer, InOrderFramesAreAllAccepted) {
  Sequencer s;
  for (std::uint64_t k = 5; k < 100; ++k) EXPECT_EQ(s.offer(7, k), Verdict::accept);
  EXPECT_EQ(s.counters().accepted, 95u);
  EXPECT_EQ(s.counters().missing, 0u);
  EXPECT_EQ(s.lost(), 0u);
  EXPECT_EQ(s.newest(), 99u);
}

TEST(Sequencer, DuplicatesAreDroppedAndCounted) {
  Sequencer s;
  EXPECT_EQ(s.offer(1, 10), Verdict::accept);
  EXPECT_EQ(s.offer(1, 10), Verdict::duplicate);
  EXPECT_EQ(s.offer(1, 11), Verdict::accept);
  EXPECT_EQ(s.offer(1, 10), Verdict::duplicate);
  EXPECT_EQ(s.offer(1, 11), Verdict::duplicate);
  EXPECT_EQ(s.counters().duplicates, 3u);
  EXPECT_EQ(s.counters().accepted, 2u);
}

TEST(Sequencer, GapsAreCountedAndLateArrivalsFillThem) {
  Sequencer s;
  EXPECT_EQ(s.offer(1, 1), Verdict::accept);
  EXPECT_EQ(s.offer(1, 5), Verdict::accept);  // 2, 3, 4 missing
  EXPECT_EQ(s.counters().missing, 3u);
  EXPECT_EQ(s.lost(), 3u);
  EXPECT_EQ(s.offer(1, 3), Verdict::late);  // reordered: older than the newest, dropped
  EXPECT_EQ(s.lost(), 2u);
  EXPECT_EQ(s.offer(1, 3), Verdict::duplicate);  // now seen
  EXPECT_EQ(s.counters().late, 1u);
  EXPECT_EQ(s.newest(), 5u);
}

TEST(Sequencer, FramesOlderThanTheFirstAreLateButWereNeverMissing) {
  Sequencer s;
  EXPECT_EQ(s.offer(1, 10), Verdict::accept);
  EXPECT_EQ(s.offer(1, 9), Verdict::late);
  EXPECT_EQ(s.counters().late, 1u);
  EXPECT_EQ(s.counters().late_filled, 0u);
  EXPECT_EQ(s.lost(), 0u);
}

TEST(Sequencer, FramesBeyondTheWindowAreStale) {
  Sequencer s;
  EXPECT_EQ(s.offer(1, 0), Verdict::accept);
  EXPECT_EQ(s.offer(1, 200), Verdict::accept);
  EXPECT_EQ(s.offer(1, 136), Verdict::stale);  // age 64
  EXPECT_EQ(s.offer(1, 137), Verdict::late);   // age 63: remembered as not seen
  EXPECT_EQ(s.offer(1, 0), Verdict::stale);
  EXPECT_EQ(s.counters().stale, 2u);
  EXPECT_EQ(s.counters().missing, 199u);
}

TEST(Sequencer, ANewStreamIdStartsOver) {
  Sequencer s;
  EXPECT_EQ(s.offer(1, 1000), Verdict::accept);
  EXPECT_EQ(s.offer(2, 0), Verdict::accept);  // the appliance restarted
  EXPECT_EQ(s.offer(2, 1), Verdict::accept);
  EXPECT_EQ(s.offer(1, 1001), Verdict::accept);  // and back: another restart
  EXPECT_EQ(s.counters().stream_restarts, 2u);
  EXPECT_EQ(s.counters().missing, 0u);
}

// A shuffled stream with drops and duplicates: the accepted sequence numbers strictly
// increase, every number is accounted for exactly once, and the loss is what was dropped.
TEST(Sequencer, ShuffledStreamWithLossAndDuplicationIsAccountedFor) {
  std::mt19937_64 random(18);
  std::vector<std::uint64_t> sent;
  std::uint64_t dropped = 0;
  for (std::uint64_t k = 0; k < 5000; ++k) {
    if (k != 0 && random() % 10 == 0) {
      ++dropped;
      continue;
    }
    sent.push_back(k);
    if (random() % 20 == 0) sent.push_back(k);  // duplicated in the network
  }
  // Local reordering: swap neighbours within a distance of 8.
  for (std::size_t i = 0; i + 8 < sent.size(); ++i)
    if (random() % 4 == 0) std::swap(sent[i], sent[i + 1 + random() % 7]);
  // The first frame must be the stream's first for the loss count to be exact.
  std::iter_swap(sent.begin(), std::min_element(sent.begin(), sent.end()));

  Sequencer s;
  std::uint64_t last_accepted = 0;
  bool any = false;
  std::uint64_t offered = 0;
  for (const std::uint64_t k : sent) {
    ++offered;
    if (s.offer(3, k) == Verdict::accept) {
      if (any) {
        EXPECT_GT(k, last_accepted);
      }
      last_accepted = k;
      any = true;
    }
  }
  const Sequencer::Counters& c = s.counters();
  EXPECT_EQ(c.accepted + c.duplicates + c.late + c.stale, offered);
  EXPECT_EQ(c.stale, 0u);  // reordering never reaches 64 back
  EXPECT_EQ(s.newest(), *std::max_element(sent.begin(), sent.end()));
  // Every number below the newest was either accepted, late, or never arrived.
  EXPECT_EQ(c.accepted + c.late - 1 + s.lost(), s.newest());
  const std::uint64_t dropped_below_newest = s.newest() + 1 - (c.accepted + c.late);
  EXPECT_EQ(s.lost(), dropped_below_newest);
  EXPECT_LE(s.lost(), dropped);
  EXPECT_GT(c.duplicates, 0u);
  EXPECT_GT(c.late, 0u);
}

}  // namespace
}  // namespace trainer::telemetry
