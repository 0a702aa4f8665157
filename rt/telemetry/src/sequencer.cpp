#include "trainer/telemetry/sequencer.hpp"

namespace trainer::telemetry {

Sequencer::Verdict Sequencer::offer(std::uint32_t stream_id, std::uint64_t sequence) noexcept {
  if (!has_stream_ || stream_id != stream_id_) {
    if (has_stream_) ++counters_.stream_restarts;
    has_stream_ = true;
    stream_id_ = stream_id;
    first_ = sequence;
    newest_ = sequence;
    seen_ = 1;
    ++counters_.accepted;
    return Verdict::accept;
  }
  if (sequence > newest_) {
    const std::uint64_t step = sequence - newest_;
    counters_.missing += step - 1;
    seen_ = step >= 64 ? 0 : seen_ << step;
    seen_ |= 1;
    newest_ = sequence;
    ++counters_.accepted;
    return Verdict::accept;
  }
  const std::uint64_t age = newest_ - sequence;
  if (age >= 64) {
    ++counters_.stale;
    return Verdict::stale;
  }
  const std::uint64_t bit = std::uint64_t{1} << age;
  if ((seen_ & bit) != 0) {
    ++counters_.duplicates;
    return Verdict::duplicate;
  }
  seen_ |= bit;
  ++counters_.late;
  if (sequence > first_) ++counters_.late_filled;  // was counted missing when skipped
  return Verdict::late;
}

}  // namespace trainer::telemetry
