// Time source for the loop and for simulated devices. The real clock is CLOCK_MONOTONIC with
// absolute-deadline sleeps; tests inject a manual clock so scheduling and overrun policy are
// checked deterministically, without depending on the machine's timing.
#pragma once

#include <cstdint>

namespace trainer::core {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual std::int64_t now_ns() noexcept = 0;
  // Sleep until the absolute time `deadline_ns` on this clock (returns at once if past).
  virtual void sleep_until_ns(std::int64_t deadline_ns) noexcept = 0;
};

// CLOCK_MONOTONIC + clock_nanosleep(TIMER_ABSTIME), retried on EINTR.
class MonotonicClock final : public Clock {
 public:
  std::int64_t now_ns() noexcept override;
  void sleep_until_ns(std::int64_t deadline_ns) noexcept override;
};

// CLOCK_MONOTONIC slowed down by a whole factor: now_ns() = CLOCK_MONOTONIC / factor, and
// sleeps last `factor` times longer. Two processes with the same factor share one time line
// (the trainer and simdrive in the bench VM), so periods, heartbeats and deadlines keep their
// ratios while an emulator that runs code 20x slower than the hardware keeps up. A tool for
// emulators and debugging, never the appliance's setting: timing measured on it means nothing.
class SlowMotionClock final : public Clock {
 public:
  explicit SlowMotionClock(std::int64_t factor) noexcept : factor_(factor < 1 ? 1 : factor) {}
  std::int64_t now_ns() noexcept override;
  void sleep_until_ns(std::int64_t deadline_ns) noexcept override;
  std::int64_t factor() const noexcept { return factor_; }

 private:
  MonotonicClock wall_;
  std::int64_t factor_;
};

// Deterministic clock for tests and offline runs: time moves only when told to.
// sleep_until_ns jumps to the deadline plus the injected wake-up latency (applied to every
// sleep until changed).
class ManualClock final : public Clock {
 public:
  explicit ManualClock(std::int64_t start_ns = 0) noexcept : now_(start_ns) {}
  std::int64_t now_ns() noexcept override { return now_; }
  void sleep_until_ns(std::int64_t deadline_ns) noexcept override {
    if (deadline_ns > now_) now_ = deadline_ns;
    now_ += wake_latency_ns_;
  }
  void advance_ns(std::int64_t delta_ns) noexcept { now_ += delta_ns; }
  void set_wake_latency_ns(std::int64_t latency_ns) noexcept { wake_latency_ns_ = latency_ns; }

 private:
  std::int64_t now_;
  std::int64_t wake_latency_ns_ = 0;
};

}  // namespace trainer::core
