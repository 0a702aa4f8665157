// Receiver-side ordering of the telemetry stream: UDP may lose, duplicate and reorder
// datagrams, and a display only wants the newest state. offer() says whether a decoded frame
// is to be shown: newer than every frame accepted so far in its stream (newest wins), or a
// duplicate / late (reordered) frame that is dropped. Gaps in the sequence are counted when
// a newer frame skips numbers; a skipped number that turns up later counts as late, so
// lost = missing − late_filled. A frame of another stream id (the appliance restarted)
// starts over. O(1), no heap: the last 64 sequence numbers are remembered as a bit set to tell
// a duplicate from a late frame.
#pragma once

#include <cstdint>

namespace trainer::telemetry {

class Sequencer {
 public:
  enum class Verdict : std::uint8_t {
    accept,     // newest so far: show it
    duplicate,  // this sequence number was already seen: drop
    late,       // older than the newest, not seen before (reordered): drop
    stale,      // older than the 64 remembered: drop (duplicate or late, unknown)
  };

  struct Counters {
    std::uint64_t accepted = 0;
    std::uint64_t duplicates = 0;
    std::uint64_t late = 0;         // reordered frames dropped (not seen before)
    std::uint64_t stale = 0;
    std::uint64_t missing = 0;      // sequence numbers skipped by accepted frames
    std::uint64_t late_filled = 0;  // of `missing`, how many arrived later (also in `late`)
    std::uint64_t stream_restarts = 0;  // a new stream id after the first
  };

  Verdict offer(std::uint32_t stream_id, std::uint64_t sequence) noexcept;

  const Counters& counters() const noexcept { return counters_; }
  // Skipped numbers never seen: lost (or still in flight).
  std::uint64_t lost() const noexcept { return counters_.missing - counters_.late_filled; }
  bool has_stream() const noexcept { return has_stream_; }
  std::uint64_t newest() const noexcept { return newest_; }
  void reset() noexcept { *this = Sequencer{}; }

 private:
  bool has_stream_ = false;
  std::uint32_t stream_id_ = 0;
  std::uint64_t first_ = 0;   // the stream's first accepted sequence number
  std::uint64_t newest_ = 0;
  std::uint64_t seen_ = 0;  // bit k: newest_ − k was seen (bit 0 is newest_ itself)
  Counters counters_;
};

}  // namespace trainer::telemetry
